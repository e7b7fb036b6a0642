"""Readers that turn what a lab recorded into one table of impacts.

Every reader returns a :class:`pandas.DataFrame` with one row per impact, sorted by time, and
these columns (SI units):

=====================  ======  =============================================================
column                 unit    meaning
=====================  ======  =============================================================
``time``               s       impact time (audio: onset of the impact transient)
``time_uncertainty``   s       1σ uncertainty of ``time``
``amplitude``          1       peak amplitude of the transient, full scale = 1 (NaN if none)
``impact_speed``       m/s     measured speed just before the impact (NaN if not measured)
``rebound_speed``      m/s     measured speed just after the impact (NaN if not measured)
``speed_uncertainty``  m/s     1σ uncertainty of the speeds (NaN if not measured)
``run``                –       run index for files holding several runs side by side (0 if one)
=====================  ======  =============================================================

``DataFrame.attrs`` holds ``source`` (the file), ``sensor`` (the reader's kind) and ``notes``
(a list of plain-words remarks, e.g. which time unit was inferred). Bad input raises
:class:`dashpot.errors.InputError` naming the file, the row where it applies, and the problem.
"""

IMPACT_COLUMNS = ("time", "time_uncertainty", "amplitude", "impact_speed", "rebound_speed",
                  "speed_uncertainty", "run")
