"""Kalibr values: noise density from the short-term terms, random walk from the slow terms only."""

import numpy as np

from bayes_imu import NoiseModel
from bayes_imu.report.kalibr import axis_densities
from bayes_imu.inference.population import UnitPosterior


def test_short_term_terms_set_the_density_and_slow_biases_the_random_walk():
    """White q plus filtered white c (autocovariances 2c, c: long-time white level 2c + 2c = 4c)
    plus a fast AR(1) (sum of autocovariances s^2 (1 + phi)/(1 - phi)) give the density
    sqrt(q_eff dt); the random walk is sqrt(2 s^2 / T) of each slow bias and K, never the fast
    term."""
    dt = 0.01
    draws = {"noise_variance": np.array([2e-5]), "filtered_variance": np.array([6e-6]),
             "correlated_variance": np.array([1e-6]), "correlated_time_constant": np.array([0.03]),
             "bias_variance": np.array([4e-8]), "time_constant": np.array([100.0]),
             "bias_variance_2": np.array([1e-8]), "time_constant_2": np.array([1000.0]),
             "rate_random_walk": np.array([1e-6])}
    model = NoiseModel(
        (
            "white",
            "filtered_white",
            "hf_correlated",
            "gauss_markov",
            "gauss_markov_2",
            "random_walk",
        ),
        dt,
    )
    fit = UnitPosterior(model, np.column_stack([draws[n] for n in model.parameter_names]), 1e4)
    density, walk = axis_densities(fit, 2.0)
    phi = np.exp(-dt / 0.03)
    q_eff = 2e-5 + 4 * 6e-6 + 1e-6 * (1 + phi) / (1 - phi)
    np.testing.assert_allclose(density, 2.0 * np.sqrt(q_eff * dt), rtol=1e-12)
    np.testing.assert_allclose(
        walk, 2.0 * np.sqrt(2 * 4e-8 / 100 + 2 * 1e-8 / 1000 + 1e-12), rtol=1e-12
    )


def test_one_sensor_several_axes_and_topic(tmp_path, capsys):
    """A gyro alone (two axes): only the gyroscope keys, the worst axis stated, each axis in a
    comment, the topic as given; the worst-axis value is the larger of the axes' own medians."""
    import json

    from bayes_imu.cli.main import main

    rng = np.random.default_rng(11)
    rows = rng.standard_normal((2**13, 2)) * [0.01, 0.03]
    log = tmp_path / "imu.csv"
    log.write_text("gx,gy\n" + "".join(f"{a:.7f},{b:.7f}\n" for a, b in rows))
    assert (
        main(
            [
                "fit",
                str(log),
                "--column",
                "gx,gy",
                "--rate",
                "100",
                "--units",
                "rad/s",
                "--terms",
                "white",
                "--out",
                str(tmp_path / "g"),
                "--quiet",
            ]
        )
        == 0
    )
    assert main(["kalibr", "--gyro", str(tmp_path / "g"), "--topic", "/body/imu", "--out",
                 str(tmp_path / "imu.yaml")]) == 0
    text = (tmp_path / "imu.yaml").read_text()
    keys = dict(line.split(": ") for line in text.splitlines() if not line.startswith("#"))
    assert set(keys) == {
        "gyroscope_noise_density",
        "gyroscope_random_walk",
        "rostopic",
        "update_rate",
    }
    assert keys["rostopic"] == "/body/imu" and "worst axis" in text.splitlines()[0]
    assert "# gyroscope_noise_density per axis: " in text
    axes = json.loads((tmp_path / "g" / "summary.json").read_text())["axes"]
    medians = [a["parameters"]["noise_density"]["median"] for a in axes.values()]
    assert float(keys["gyroscope_noise_density"]) == max(medians) or \
        abs(float(keys["gyroscope_noise_density"]) / max(medians) - 1) < 1e-6
    assert max(medians) / min(medians) > 2.5  # the two axes differ by 3x: the worst one is taken
    assert main(["kalibr", "--out", str(tmp_path / "none.yaml")]) == 2
    assert "--gyro" in capsys.readouterr().err
    assert (
        main(
            [
                "kalibr",
                "--gyro",
                str(tmp_path / "g"),
                "--topic",
                "imu 0",
                "--out",
                str(tmp_path / "t.yaml"),
            ]
        )
        == 2
    )
    assert "ROS topic" in capsys.readouterr().err
