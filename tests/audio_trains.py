"""What the synthetic audio tests share: the bounce trains they record, and stand-ins for a
probe of the file.

The trains: a ball of the hybrid contact model whose damping, natural frequency and first
impact speed are drawn from the given generator, up to the bounces 6 ms apart: the last
intervals a recording can time against rings a few ms long, and short trains keep the tests
within the suite's time.
"""

import numpy as np

import dashpot
from dashpot.ingest.chain import _robust_trend


def hybrid_train(rng, n_max=400):
    """Impact times (s, the first at 0) and impact speeds (m/s) of one train; three draws from
    `rng`, in this order: β (1/s), ω0 (rad/s), v0 (m/s)."""
    return hybrid_drops(rng, 1, n_max)[2][0]


def hybrid_drops(rng, count, n_max=400):
    """β (1/s), ω0 (rad/s) and the (impact times, s, the first at 0; impact speeds, m/s) of
    `count` drops of one ball; draws from `rng`, in this order: β, ω0, then v0 (m/s) of each
    drop."""
    beta, omega0 = rng.uniform(40, 150), rng.uniform(2000, 4000)
    drops = []
    for v0 in rng.uniform(0.5, 0.9, size=count):
        sequence = dashpot.bounce_sequence("hybrid", beta=beta, omega0=omega0, g=9.81, v0=v0,
                                           n_max=n_max)
        keep = np.cumprod(np.concatenate([[True], sequence.intervals >= 6e-3])).astype(bool)
        drops.append((sequence.impact_times[keep], sequence.impact_speeds[keep]))
    return beta, omega0, drops


def onset_near(sounds, predicted, tolerance, amplitude=1.0):
    """What a probe of the file finds near `predicted` (s) where the file holds `sounds` (s):
    the nearest within `tolerance` (s), as (time, 1σ, amplitude, clipped), or None."""
    nearest = sounds[np.abs(sounds - predicted).argmin()]
    return (nearest, 1e-5, amplitude, False) if abs(nearest - predicted) <= tolerance else None


def timed_at_a_secondary(cause, lead):
    """Impacts shrinking by 0.9 (times, s), where a secondary of impact `cause` recurs `lead`
    (s) before impact 12, whose onset was taken at that secondary's start: the impacts, the
    secondary's delay (s), the impacts as timed, and the trend of the impacts
    (:func:`dashpot.ingest.chain._robust_trend`)."""
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(30))
    timed = impacts.copy()
    timed[12] -= lead
    return impacts, impacts[12] - impacts[cause] - lead, timed, _robust_trend(impacts)


def score_train(onsets, found, sigma, match=1e-3):
    """How a detection `found` (s, with its 1σ `sigma`, s) times the true `onsets` (s): a
    detection within `match` (s) of a true onset is that impact (the nearest one to it).

    Returns
    -------
    dict
        ``found``: true impacts timed, ``timed`` which (one per detection: the first true
        onset it is nearest to); ``false``: detections that are no impact, ``false_times``
        theirs (s), ``after`` of them past the last true onset; ``z``: |error| / 1σ of each
        impact timed.
    """
    distance = np.abs(onsets[:, None] - found[None, :])
    nearest = distance.argmin(axis=1)
    hit = distance[np.arange(onsets.size), nearest] < match
    owned = np.zeros(found.size, dtype=bool)
    owned[nearest[hit]] = True
    timed = np.zeros(onsets.size, dtype=bool)
    timed[np.flatnonzero(hit)[np.unique(nearest[hit], return_index=True)[1]]] = True
    return dict(found=int(timed.sum()), timed=timed, false=int((~owned).sum()),
                false_times=found[~owned],
                after=int((~owned & (found > onsets[-1] + match)).sum()),
                z=np.abs(found[nearest[hit]] - onsets[hit]) / sigma[nearest[hit]])
