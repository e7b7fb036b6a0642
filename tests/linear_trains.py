"""What the exactness tests of the speed filters share: the linear Gaussian train they filter
and the exact likelihood they compare with.

The train: every rebound is V(1 + η_n) whatever the impact speed, contacts last a fixed
time, and the flights have the incline's two accelerations, so that every time and speed is a
linear map of Gaussian noises and the Kalman filter's −2 ln L must equal that of their
multivariate normal.
"""

import numpy as np
from scipy import stats

from dashpot.likelihood import TrainModel
from dashpot.physics.flight import track_flight


def linear_train_model(rebound, up, down, contact):
    """TrainModel of rebound speed `rebound` (m/s) whatever the impact speed, flights with the
    accelerations `up` and `down` (m/s², away from and toward the surface) and contacts of
    `contact` (s)."""
    return TrainModel(lambda u: (np.full_like(u, rebound), np.zeros_like(u)),
                      lambda v: track_flight(v, up, down),
                      lambda u: (np.full_like(u, contact), np.zeros_like(u)))


def exact_neg2_log_likelihood(times, impact, rebounds, base, mean, covariance):
    """−2 ln L of each row's observations under the multivariate normal (`mean`,
    `covariance`) of [times − first time (s), impact speeds, rebound speeds (m/s)], missing
    values (NaN) left out; `base` (s) is the first time, the same in every row."""
    count = times.shape[1]
    result = []
    for row in range(times.shape[0]):
        observed = np.concatenate([times[row, 1:], impact[row], rebounds[row]])
        seen = np.isfinite(observed)
        values = observed - np.concatenate([np.full(count - 1, base), np.zeros(2 * count)])
        result.append(-2.0 * stats.multivariate_normal(
            mean[seen], covariance[np.ix_(seen, seen)]).logpdf(values[seen]))
    return np.array(result)
