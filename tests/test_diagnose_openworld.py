"""fleetrun diagnose in the open world (issues 11, 16): what the catalogue does not hold is
reported as unexplained, by its size, after the physics the catalogue can name; integrals per
phase; the same-trace residual; the effects added to the catalogue (mesh friction, oil churning).

Out-of-catalogue causes come from fleetrun.testing.recordings.OUT_OF_CATALOGUE: a torque
share lost at every speed (issue 11's "3 % torque-proportional loss"), a loss growing with
the square of the load (mesh misalignment under deflection) and a loss with a memory of the
load history (a mesh heating under sustained load). None is a basis function of the fitter;
each is hidden in the same recordings as the catalogue cases (AR(1) noise, offsets).
"""
import numpy as np
import pytest

from fleetrun.diagnose import diagnose
from fleetrun.diagnose.integrals import GAP_S, phases
from fleetrun.resources import inputs_dir
from fleetrun.testing.recordings import OUT_OF_CATALOGUE, generate_differential_recording, unknown_case

CAUSES = list(OUT_OF_CATALOGUE)


def _unexplained(res) -> bool:
    return res["unexplained"]["significant"] is True


@pytest.mark.parametrize("cause", CAUSES)
def test_out_of_catalogue_cause_is_unexplained(tmp_path, cause):
    # physics first: catalogue effects may describe part of the cause (issue 16), but what
    # they leave is reported as unexplained, with its size
    rec = unknown_case(cause, 0)
    res = diagnose(rec.write(tmp_path / f"{cause}.csv"), write=False)
    assert _unexplained(res), (res["findings"], res["unexplained"])
    u = res["unexplained"]
    # what is left is well above what no function of the channels explains (an upper bound of
    # the noise: 1.5 N m AR(1) on the output torque)
    assert u["rmse"] > 1.5 * u["noise_rmse"]
    assert 0 < u["energy_share"] <= 1
    assert u["integral_share"] is not None


def test_catalogue_effect_leaves_nothing_unexplained(tmp_path):
    from fleetrun.testing.recordings import random_case

    rec = random_case(["cornering"], 41)
    res = diagnose(rec.write(tmp_path / "c.csv"), write=False)
    assert [f["effect"] for f in res["findings"]] == ["cornering"]
    assert res["unexplained"]["significant"] is False
    assert set(res["unexplained"]) >= {"significant", "rmse", "noise_rmse", "segments", "drivers"}


def test_html_and_cli_say_unexplained_first(tmp_path):
    from click.testing import CliRunner

    from fleetrun.cli import cli

    path = unknown_case("torque_share_loss", 1).write(tmp_path / "share.csv")
    out = tmp_path / "d"
    res = CliRunner().invoke(cli, ["diagnose", str(path), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "unexplained:" in res.output
    html = (out / "diagnosis.html").read_text()
    first = html.index("<strong>Finding.</strong>")
    assert html.index("Something the catalogue does not describe remains", first) < html.index("<h2>")


# ----------------------------------------------------------------------------- new effects
def test_mesh_friction_follows_dudley_eq_12_36():
    """1 - eta of the reference hypoid (thesis B.2 geometry: phi_n 20 deg, psi_p = acos(1.75/
    2.9375), psi_g = acos(1.3125/1.46875), 12 pinion teeth, gaps 0.1875 in and 1.46875 in)
    with Dudley's f = 0.8/(v+100)^0.5, computed here from the printed numbers."""
    from fleetrun.effects.differential import hypoid_mesh_loss_share

    n = np.array([0.0, 500.0, 2000.0])
    v = n / 12 * np.sqrt(0.1875 ** 2 + 1.46875 ** 2 / 4) * 12
    f = 0.8 / np.sqrt(v + 100)
    c, tp, tg = np.cos(np.radians(20)), np.tan(np.arccos(1.75 / 2.9375)), np.tan(np.arccos(1.3125 / 1.46875))
    expected = 1 - (c + f * tg) / (c + f * tp)
    np.testing.assert_allclose(hypoid_mesh_loss_share(n * 2 * np.pi / 60), expected, rtol=1e-9)


def test_oil_churning_grows_as_speed_squared():
    # Dudley's bevel windage (thesis Eq. 5.10) is quadratic in speed and linear in X
    from fleetrun.effects.differential import ring_gear_churning_torque_Nm

    w = np.array([100.0, 200.0])
    t = ring_gear_churning_torque_Nm(w, 3.55)
    assert t[1] / t[0] == pytest.approx(4.0, rel=1e-9)
    assert ring_gear_churning_torque_Nm(w, 4.1)[0] < t[0]        # slower ring gear


@pytest.mark.parametrize("effect,params", [("mesh_friction", {"friction_excess": 0.6}),
                                           ("oil_churning", {"immersion_excess": 0.6})])
def test_new_catalogue_effects_are_found(tmp_path, effect, params):
    rec = generate_differential_recording([(effect, params)], seed=1, offset_out_Nm=2.0)
    res = diagnose(rec.write(tmp_path / "e.csv"), write=False)
    f = res["findings"]
    assert [x["effect"] for x in f] == [effect], (f, res["descriptions"])
    (name, value), = params.items()
    assert f[0]["parameters"][name] == pytest.approx(value, rel=0.1)
    assert f[0]["heldout_rmse_after"] < f[0]["heldout_rmse_before"]


# ----------------------------------------------------------------------------- integrals
def test_phases_split_at_long_standstill_and_udds_bag_boundary():
    from fleetrun.cycles import load_cycle

    u = load_cycle("UDDS")
    v_u = np.asarray(u.speed_mps, float)
    v = np.concatenate([v_u, np.zeros(int(GAP_S) + 40), v_u[:300]])
    t = np.arange(len(v), dtype=float)
    spans = phases(t, v > 0.1, v)
    labels = [p.label for p in spans]
    assert labels[:3] == ["UDDS bag 1", "UDDS bag 2", "standstill"]
    assert t[spans[1].span[0]] == 505.0          # 40 CFR 86.137: bag 1 ends at 505 s
    assert spans[-1].label == "driving"           # 300 s of UDDS: not a whole first bag


def test_camry_cold_vs_hot_integrals_same_trace(tmp_path):
    """Issue 11, done when: warm-up named first; the first phase's (0-505 s) fuel error at
    least halved; no later phase worse by more than 1 % of its measured fuel."""
    dyno = inputs_dir() / "dyno"
    res = diagnose(dyno / "camry2018_udds_cold.csv", calibrate_on=dyno / "camry2018_udds_hot.csv",
                   write=False)
    assert res["baseline"]["residual"] == "same_trace"
    assert res["findings"][0]["effect"] == "warmup"
    ph = [e for e in res["integrals"] if e["kind"] == "phase"]
    assert (ph[0]["start_s"], ph[0]["end_s"]) == (0.0, 505.0)
    err = [(abs(e["before"] - e["measured"]), abs(e["after"] - e["measured"]), e["measured"]) for e in ph]
    assert err[0][1] <= 0.5 * err[0][0]
    assert all(after - before <= 0.01 * m for before, after, m in err[1:])
    # the same run with the calibrated simulation as the residual names the warm-up too
    sim = diagnose(dyno / "camry2018_udds_cold.csv", calibrate_on=dyno / "camry2018_udds_hot.csv",
                   write=False, residual="simulation")
    assert sim["baseline"]["residual"] == "simulation" and sim["findings"][0]["effect"] == "warmup"
