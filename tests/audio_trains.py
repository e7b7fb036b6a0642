"""The bounce trains the synthetic audio tests record.

A ball of the hybrid contact model whose damping, natural frequency and first impact speed
are drawn from the given generator, up to the bounces 6 ms apart: the last intervals a
recording can time against rings a few ms long, and short trains keep the tests within the
suite's time.
"""

import numpy as np

import dashpot


def hybrid_train(rng, n_max=400):
    """Impact times (s, the first at 0) and impact speeds (m/s) of one train; three draws from
    `rng`, in this order: β (1/s), ω0 (rad/s), v0 (m/s)."""
    sequence = dashpot.bounce_sequence("hybrid", beta=rng.uniform(40, 150),
                                       omega0=rng.uniform(2000, 4000), g=9.81,
                                       v0=rng.uniform(0.5, 0.9), n_max=n_max)
    keep = np.cumprod(np.concatenate([[True], sequence.intervals >= 6e-3])).astype(bool)
    return sequence.impact_times[keep], sequence.impact_speeds[keep]
