"""`--physics thesis` is Appendix B as printed: parity with independently computed values.

1. Every row of ../shared/reference/thesis_grid.csv (the thesis code evaluated by an
   independent numpy port with MATLAB semantics), through the library and through
   `fleetrun map`, to 1e-9 relative (1e-12 absolute where the value is 0): the tolerance the
   reference README fixes; the two ports differ only in floating-point operation order.
2. Any torque fraction, speed and gear ratio: a seeded random sample (including the
   scaling branches g < G, g = G, g > G and tiny/zero torque) against tests/thesis_oracle.py,
   a literal scalar transcription of B.1-B.4, B.6, B.7 written from the printed code.
"""
import csv
import io
import random
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import thesis_oracle as oracle
from fleetrun.cli import cli
from fleetrun.differential import efficiency

REFERENCE = Path(__file__).resolve().parent / "data" / "thesis_grid.csv"
SHARED_REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "thesis_grid.csv"


def close(got, want):
    return abs(got - want) <= 1e-9 * max(abs(want), 1e-3) or abs(got - want) <= 1e-12


def reference_groups():
    groups = {}
    for r in csv.DictReader(REFERENCE.open()):
        key = (r["configuration"], r["gear_ratio"], r["low_gear_ratio"], r["axle_gear"])
        groups.setdefault(key, []).append(r)
    return groups


@pytest.mark.skipif(not SHARED_REFERENCE.exists(), reason="../shared not beside this checkout")
def test_copy_of_reference_is_current():
    assert REFERENCE.read_bytes() == SHARED_REFERENCE.read_bytes()


def test_reference_has_every_configuration():
    configs = {k[0] for k in reference_groups()}
    assert {"LD_FWD", "LD_RWD", "LD_4WD", "LD_AWD", "HD_RWD", "HD_DUAL", "HD_TANDEM",
            "HD_TANDEM_DUAL"} <= configs


def test_library_matches_every_reference_row():
    bad, total = [], 0
    for (config, g, lo, gear), rows in reference_groups().items():
        tf = np.array([float(r["torque_fraction"]) for r in rows])
        n = np.array([float(r["speed_rpm"]) for r in rows])
        kw = dict(low_gear_ratio=float(lo), axle_gear=gear) if lo else {}
        got = efficiency(config, tf, n, float(g), **kw)
        for r, value in zip(rows, got):
            total += 1
            if not close(float(value), float(r["efficiency"])):
                bad.append((config, g, lo, gear, r["torque_fraction"], r["speed_rpm"], value, r["efficiency"]))
    assert total == 1159
    assert not bad, bad[:5]


def test_map_command_matches_every_reference_row():
    runner = CliRunner()
    total = 0
    for (config, g, lo, gear), rows in reference_groups().items():
        tfs = list(dict.fromkeys(r["torque_fraction"] for r in rows))
        speeds = list(dict.fromkeys(r["speed_rpm"] for r in rows))
        args = ["map", config, "--gear-ratio", g, "--physics", "thesis", "--torque-fractions", ",".join(tfs),
                "--speeds-rpm", ",".join(speeds)]
        if lo:
            args += ["--low-gear-ratio", lo, "--axle-gear", gear]
        result = runner.invoke(cli, args)
        assert result.exit_code == 0, result.output
        got = {(float(r["torque_fraction"]), float(r["speed_rpm"])): float(r["efficiency"])
               for r in csv.DictReader(io.StringIO(result.output))}
        for r in rows:
            total += 1
            value = got[(float(r["torque_fraction"]), float(r["speed_rpm"]))]
            assert close(value, float(r["efficiency"])), (config, g, lo, gear, r)
    assert total == 1159


@pytest.mark.parametrize("config", ["LD_FWD", "LD_RWD", "LD_4WD", "LD_AWD", "HD_RWD", "HD_TAG", "HD_TANDEM"])
def test_any_point_matches_literal_transcription(config):
    rng = random.Random(f"fleetrun-{config}")
    refs = [2.6521739130434782608695652173913, 41 / 12, 3.9]
    for _ in range(150):
        tf = rng.choice([0.0, 1e-5, 0.002, 0.02, rng.random(), rng.uniform(0, 3)])
        n = rng.choice([0.0, 0.5, rng.uniform(0, 7000)])
        g = rng.choice([rng.uniform(1.05, 9.0), rng.choice(refs), rng.choice(refs) * (1 + 1e-12), 3.0])
        want = oracle.configuration_efficiency(config, tf, n, g)
        got = float(efficiency(config, tf, n, g))
        assert close(got, want), (config, tf, n, g, got, want)


def test_dual_uses_b5_then_b4():
    """HD_DUAL = B.5, which ends by calling B.4 on the box's output (reference README)."""
    from fleetrun.physics.two_speed_box import auxiliary_box

    rng = random.Random(7)
    for _ in range(40):
        tf, n, g = rng.uniform(0.01, 1.5), rng.uniform(1, 5000), rng.uniform(2.0, 7.0)
        lo, gear = rng.choice([4.900735, 1.35, 3.0]), rng.choice(["low", "high"])
        eta_box, tf_out, n_out = auxiliary_box(tf, n, lo, gear)
        want = float(eta_box) * oracle.eff_diff_rear_hd(float(tf_out), float(n_out), g)[0]
        got = float(efficiency("HD_DUAL", tf, n, g, low_gear_ratio=lo, axle_gear=gear))
        assert close(got, want)
        tandem = float(efficiency("HD_TANDEM_DUAL", tf, n, g, low_gear_ratio=lo, axle_gear=gear))
        assert close(tandem, want * oracle.eff_diff_trans(tf, n, g)[0])


def test_array_and_scalar_agree_and_shapes_broadcast():
    tf = np.linspace(0, 1, 7)[:, None]
    n = np.linspace(0, 4000, 5)[None, :]
    grid = efficiency("LD_RWD", tf, n, 3.73)
    assert grid.shape == (7, 5)
    assert grid[3, 2] == pytest.approx(float(efficiency("LD_RWD", tf[3, 0], n[0, 2], 3.73)), rel=1e-15)
    ratios = np.array([[3.0], [4.1]])
    mixed = efficiency("HD_RWD", 0.4, np.array([[1000.0, 2000.0]]), ratios)
    assert mixed.shape == (2, 2)
    assert mixed[1, 0] == pytest.approx(float(efficiency("HD_RWD", 0.4, 1000.0, 4.1)), rel=1e-15)


def test_zero_torque_gives_zero_as_b6():
    """At torque fraction 0 every stage divides a loss by zero torque: B.6 returns 0."""
    assert np.all(efficiency("LD_FWD", 0.0, [0, 1000, 4000], 3.0) == 0.0)


def test_array_low_gear_ratios_match_scalar_calls():
    lows = np.array([4.900735, 1.35, 4.900735, 3.0])
    got = efficiency("HD_DUAL", 0.3, np.array([800.0, 1200.0, 1600.0, 2000.0]), 3.7, low_gear_ratio=lows,
                     axle_gear="low")
    for i, lo in enumerate(lows):
        want = float(efficiency("HD_DUAL", 0.3, [800.0, 1200.0, 1600.0, 2000.0][i], 3.7, low_gear_ratio=lo,
                                axle_gear="low"))
        assert got[i] == want


def test_input_torque_scale_matters_to_vecto_only():
    thesis = [float(efficiency("HD_RWD", 0.3, 1000, 3.7, kim_torque_scale_Nm=s)) for s in (5000, 30000)]
    assert thesis[0] == thesis[1]
    vecto = [float(efficiency("HD_RWD", 0.3, 1000, 3.7, physics="vecto-generic", kim_torque_scale_Nm=s))
             for s in (5000, 30000)]
    assert vecto[0] < vecto[1]  # the same drag is a larger share of a smaller torque
