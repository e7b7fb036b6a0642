"""Synthetic recordings with known truth, for testing the readers and the analysis end to end."""
