"""The motion reader at the rates motion sensors and accelerometers record at (50-400 Hz):
every fast bounce found, nothing found that is not a contact, each impact timed within 4 of
its stated σ. Exports written by the project's Capstone writer from bounce trains with a
known truth; seeds from a block never used while developing the reader."""

import numpy as np
import pytest

from dashpot.ingest import read_impacts
from dashpot.physics.sequence import bounce_sequence
from dashpot.synth.tables import write_motion_sensor

SEED = 20261125 + 7000  # a fresh block; never changed to make a test pass
G_EFF = 2.895906542614473  # m/s², the paper's cart on its incline


def _check_runs(path, truth, fastest):
    """Every run: the impacts of at least `fastest` m/s all found; every impact found is a
    distinct true one, timed within 4σ (a contact found where there is none, or one found
    twice, fails)."""
    impacts = read_impacts(path)
    for run, true in enumerate(truth["runs"]):
        found = impacts[impacts["run"] == run]
        times = np.asarray(true["impact_times"])
        nearest = np.abs(found["time"].to_numpy()[:, None] - times[None, :]).argmin(axis=1)
        pull = (found["time"].to_numpy() - times[nearest]) / found["time_uncertainty"]
        assert np.unique(nearest).size == nearest.size, (true["label"], nearest)
        assert np.all(np.abs(pull) <= 4.0), (true["label"], pull)
        fast = np.flatnonzero(np.asarray(true["impact_speeds"]) >= fastest)
        assert set(fast) <= set(nearest), (true["label"], fast, nearest)


@pytest.mark.parametrize(("rate", "noise"), [(100.0, 1e-3), (200.0, 3e-4), (400.0, 3e-4)])
def test_hard_cart_at_high_rates(tmp_path, rate, noise):
    """A cart on a hard bumper (ω0 = 300 rad/s: contacts of about 10 ms, one sample at 100
    Hz), three runs per export: found at 100-400 Hz as at 50 Hz. Reading the record as is,
    with central differences of samples 2.5-10 ms apart, found almost nothing; a derivative
    over ~20 ms found contacts while the cart was held."""
    train = bounce_sequence("hybrid", beta=5.0, omega0=300.0, g=G_EFF, v0=1.0, n_max=30)
    path = tmp_path / "capstone.csv"
    truth = write_motion_sensor(path, train, runs=3, sample_rate=rate, noise=noise,
                                seed=SEED + int(rate))
    _check_runs(path, truth, 0.36)


def test_soft_cart_at_400_hz(tmp_path):
    """The paper's cart on its soft bumper (contacts of 0.15-0.2 s, 60-80 samples at 400 Hz)."""
    train = bounce_sequence("hybrid", beta=1.87, omega0=22.448887927243977, g=G_EFF, v0=1.0,
                            n_max=30)
    path = tmp_path / "capstone.csv"
    truth = write_motion_sensor(path, train, runs=3, sample_rate=400.0, noise=3e-4,
                                seed=SEED + 1)
    impacts = read_impacts(path)
    assert any("means of 8 consecutive samples" in note for note in impacts.attrs["notes"])
    _check_runs(path, truth, 0.36)


def test_soft_cart_speeds_are_unbiased(tmp_path):
    """The paper's cart at 50 Hz, 100 single-run exports each written twice with opposite
    noise: the two readings' errors have odd parts that cancel, so the mean of each pair's
    pulls is the reader's bias, to a small fraction of σ. Over the exports it is within 3
    standard errors of zero for the impact speeds of every impact, and for the rebound speed
    of the fourth (0.36 m/s: its rebound flight of 9 mm is timed as an excursion from the
    bumper). Fitting the descent from where the velocity first passed the noise band kept
    its first samples by their own noise (the speeds came out 0.07σ high); an excursion's
    samples more than 4σ short of the bumper did the same at its ends (0.19σ high)."""
    import pandas as pd

    train = bounce_sequence("hybrid", beta=1.87, omega0=22.448887927243977, g=G_EFF, v0=1.0,
                            n_max=30)
    impact_bias, rebound_bias = [], []
    for k in range(100):  # 100 exports, two readings each (~0.1 s)
        clean = tmp_path / "clean.csv"
        truth = write_motion_sensor(clean, train, runs=1, sample_rate=50.0, noise=0.0,
                                    seed=SEED + 9000 + k, overwrite=True)["runs"][0]
        frame = pd.read_csv(clean)
        position = next(c for c in frame.columns if c.startswith("Position"))
        frame = frame[[next(c for c in frame.columns if c.startswith("Time")), position]]
        noise = 1e-3 * np.random.default_rng(SEED + 9000 + k).standard_normal(len(frame))
        pulls = []
        for sign in (1.0, -1.0):
            noisy = frame.assign(**{position: np.round(frame[position] + sign * noise, 4)})
            path = tmp_path / "capstone.csv"
            noisy.to_csv(path, index=False, float_format="%.4f")
            found = read_impacts(path)
            times = np.asarray(truth["impact_times"])
            nearest = np.abs(found["time"].to_numpy()[:, None] - times[None, :]).argmin(axis=1)
            sigma = found["speed_uncertainty"].to_numpy()
            pulls.append({n: ((v - truth["impact_speeds"][n]) / s,
                              (r - truth["rebound_speeds"][n]) / s)
                          for n, v, r, s in zip(nearest, found["impact_speed"],
                                                found["rebound_speed"], sigma)})
        both = sorted(set(pulls[0]) & set(pulls[1]))
        impact_bias.append(np.mean([(pulls[0][n][0] + pulls[1][n][0]) / 2 for n in both]))
        if 3 in both:
            rebound_bias.append((pulls[0][3][1] + pulls[1][3][1]) / 2)
    for name, values in (("impact speeds", impact_bias), ("4th rebound", rebound_bias)):
        values = np.asarray(values)
        assert values.size >= 90, name
        error = values.std(ddof=1) / np.sqrt(values.size)
        assert abs(values.mean()) <= 3.0 * error, (name, values.mean(), error)


@pytest.mark.parametrize("seed", [20282894, 20281991, 20281870])
def test_soft_cart_runs_once_misread(tmp_path, seed):
    """Three-run exports of the paper's cart at 50 Hz in which one run was read badly wrong
    (about 1 export in 300; seeds found by a pull study over many exports, not tuned on):
    impacts timed up to 116σ off, leg accelerations of 5.9 and 10.8 m/s² for 2.9. Causes: the
    direction of the bumper taken from a vote of velocity steps that long contacts tie (37 of
    74), a noise sample of the resting cart taken for a last bounce (the rest, which places
    the bumper, then lost), a noise reversal while the cart was held taken for a contact.
    Every run's impacts are now found and timed within 4σ, and both leg accelerations agree
    with the incline's within 5σ."""
    train = bounce_sequence("hybrid", beta=1.87, omega0=22.448887927243977, g=G_EFF, v0=1.0,
                            n_max=30)
    path = tmp_path / "capstone.csv"
    truth = write_motion_sensor(path, train, runs=3, sample_rate=50.0, seed=seed)
    _check_runs(path, truth, 0.36)
    for leg in read_impacts(path).attrs["accelerations"]:
        for side in ("toward", "away"):
            assert abs(leg[side] - G_EFF) <= 5.0 * leg[side + "_sd"], (leg, side)
