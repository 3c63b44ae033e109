"""fleetrun diagnose: recordings, selection on generated recordings, report, CLI.

Generated recordings come from fleetrun.testing.recordings with random seeds: the thesis
model plus hidden effects, AR(1) sensor noise (rho 0.95/sample, 1.5 N m on the output) and
sensor offsets. The full acceptance rates (issue 5, "Done when") are the slow tests at the
end; the default run keeps one case of each kind.
"""
import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.diagnose import diagnose
from fleetrun.testing.recordings import CASE_PARAMETER_RANGES, random_case
from fleetrun.diagnose.recording import load_recording
from fleetrun.errors import InputError

DIFF_EFFECTS = list(CASE_PARAMETER_RANGES)
#: Pairs are drawn from the six effects of issue 5 (the same ten pairs as before the catalogue
#: grew): mesh_friction and mixed_lubrication are both torque-proportional losses falling
#: with speed, and next to a second effect they can come out ambiguous with each other.
PAIR_EFFECTS = DIFF_EFFECTS[:6]


def _case(tmp_path, effects, seed, **kw):
    rec = random_case(effects, seed, **kw)
    path = rec.write(tmp_path / f"case_{'_'.join(effects) or 'none'}_{seed}.csv")
    return rec, path


def _single_ok(rec, res):
    """Named first, parameters within 25 %, held-out RMSE at least halved (issue 5)."""
    (eid, params), = rec.truth["effects"]
    f = res["findings"]
    if not f or f[0]["effect"] != eid:
        return False
    err = max(abs(f[0]["parameters"][k] / v - 1) for k, v in params.items())
    return err <= 0.25 and f[0]["heldout_rmse_after"] <= 0.5 * f[0]["heldout_rmse_before"]


# ----------------------------------------------------------------------------- recordings
def _write(tmp_path, df, meta=None, name="rec.csv"):
    p = tmp_path / name
    df.to_csv(p, index=False)
    meta = meta if meta is not None else {
        "configuration": "LD_RWD", "gear_ratio": 3.55, "peak_engine_torque_Nm": 400,
        "torque_converter_ratio": 3.0, "max_transmission_gear_ratio": 3.0}
    p.with_suffix(".toml").write_text("\n".join(
        f'{k} = "{v}"' if isinstance(v, str) else f"{k} = {v}" for k, v in meta.items()))
    return p


def _diff_frame(n=100):
    t = np.arange(n) * 0.1
    return pd.DataFrame({"time_s": t, "diff_input_torque_Nm": 100 + 0 * t,
                         "diff_input_speed_rpm": 1000 + 0 * t, "diff_output_torque_Nm": 340 + 0 * t})


def test_recording_errors_name_file_row_column(tmp_path):
    df = _diff_frame()
    p = _write(tmp_path, df.drop(columns="diff_input_speed_rpm"))
    with pytest.raises(InputError, match="missing column diff_input_speed_rpm"):
        load_recording(p)
    bad = df.copy()
    bad.loc[10, "time_s"] = bad.loc[9, "time_s"]
    with pytest.raises(InputError, match=r"row 12.*not strictly increasing|not strictly increasing") as e:
        load_recording(_write(tmp_path, bad))
    assert e.value.row == 12 and e.value.column == "time_s"   # header is row 1
    nan = df.copy()
    nan.loc[5, "diff_output_torque_Nm"] = np.nan
    with pytest.raises(InputError, match="NaN") as e:
        load_recording(_write(tmp_path, nan))
    assert e.value.row == 7 and e.value.column == "diff_output_torque_Nm"
    gap = df.copy()
    gap.loc[50:, "time_s"] += 30.0
    with pytest.raises(InputError, match="gap of 30.1 s"):
        load_recording(_write(tmp_path, gap))
    with pytest.raises(InputError, match="units fleetrun does not read"):
        load_recording(_write(tmp_path, df.rename(columns={"diff_input_speed_rpm": "diff_input_speed_rad_s"})))
    with pytest.raises(InputError, match="sidecar lacks gear_ratio"):
        load_recording(_write(tmp_path, df, meta={"configuration": "LD_RWD", "peak_engine_torque_Nm": 1,
                                                  "torque_converter_ratio": 1, "max_transmission_gear_ratio": 1}))
    p = tmp_path / "nosidecar.csv"
    df.to_csv(p, index=False)
    with pytest.raises(InputError, match="sidecar TOML not found"):
        load_recording(p)
    txt = df.copy().astype(object)
    txt.loc[3, "diff_input_torque_Nm"] = "abc"
    with pytest.raises(InputError, match="not a number") as e:
        load_recording(_write(tmp_path, txt))
    assert e.value.row == 5


def test_recording_axle_sum_and_resampling(tmp_path):
    df = _diff_frame().drop(columns="diff_output_torque_Nm")
    df["axle_torque_left_Nm"] = 170.0
    df["axle_torque_right_Nm"] = 171.0
    df.loc[::2, "time_s"] += 0.02          # jitter: resampled onto a uniform grid
    rec = load_recording(_write(tmp_path, df))
    assert rec.resampled
    np.testing.assert_allclose(np.diff(rec.data["time_s"]), rec.dt_s, rtol=1e-9)
    np.testing.assert_allclose(rec.data["diff_output_torque_Nm"], 341.0)


def test_vehicle_recording_units(tmp_path):
    t = np.arange(100.0)
    df = pd.DataFrame({"time_s": t, "vehicle_speed_mph": 10 + 0 * t, "fuel_rate_cc_per_s": 1 + 0 * t})
    meta = {"fuel": "gasoline", "configuration": "LD_FWD"}
    rec = load_recording(_write(tmp_path, df, meta))
    assert rec.level == "vehicle"
    np.testing.assert_allclose(rec.data["vehicle_speed_mps"], 4.4704)
    np.testing.assert_allclose(rec.data["fuel_rate_g_per_s"], 0.743)
    with pytest.raises(InputError, match="fuel rate column"):
        load_recording(_write(tmp_path, df.drop(columns="fuel_rate_cc_per_s"), meta))


# ----------------------------------------------------------------------------- CLI / report
def test_cli_writes_json_and_html(tmp_path):
    rec, path = _case(tmp_path, ["inertia"], 3, duration_s=900)
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["diagnose", str(path), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "finding: inertia" in res.output
    d = json.loads((out / "diagnosis.json").read_text())
    assert d["schema"] == "fleetrun.diagnosis/1" and d["target"] == "diff_output_torque_Nm"
    assert set(d["baseline"]) >= {"rmse", "bias", "heldout_rmse"}
    assert d["mismatch"]["significant"] is True
    assert all(set(s) >= {"start_s", "end_s", "share"} for s in d["mismatch"]["segments"])
    assert d["mismatch"]["drivers"][0]["channel"] == "acceleration"   # J dw/dt follows dw/dt
    f = d["findings"][0]
    assert f["effect"] == "inertia" and set(f) >= {"parameters", "heldout_rmse_before",
                                                   "heldout_rmse_after", "explanation"}
    assert {c["status"] for c in d["candidates"]} <= {"accepted", "rejected", "untestable", "ambiguous"}
    html = (out / "diagnosis.html").read_text()
    assert html.count("data:image/png;base64,") >= 4 and "seed 001" in html
    assert "http://" not in html and "https://" not in html   # self-contained


def test_cli_bad_input_is_one_error_line(tmp_path):
    p = _write(tmp_path, _diff_frame().drop(columns="diff_input_torque_Nm"))
    res = CliRunner().invoke(cli, ["diagnose", str(p), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1
    assert res.output.startswith("Error:") and "Traceback" not in res.output
    assert not (tmp_path / "o" / "diagnosis.json").exists()


# ----------------------------------------------------------------------------- one case of each
@pytest.mark.parametrize("effect", DIFF_EFFECTS)
def test_single_effect_found(tmp_path, effect):
    rec, path = _case(tmp_path, [effect], 11)
    res = diagnose(path, write=False)
    assert _single_ok(rec, res), (rec.truth["effects"], res["findings"], res["ambiguities"])


def test_two_effects_found(tmp_path):
    rec, path = _case(tmp_path, ["oil_warmup", "cornering"], 12)
    res = diagnose(path, write=False)
    assert {"oil_warmup", "cornering"} <= {f["effect"] for f in res["findings"]}


def test_noise_only_has_no_findings(tmp_path):
    rec, path = _case(tmp_path, [], 13)
    res = diagnose(path, write=False)
    assert res["findings"] == [] and res["ambiguities"] == []


def test_missing_wheel_speeds_cornering_untestable_not_misnamed(tmp_path):
    rec, path = _case(tmp_path, ["cornering"], 14, wheel_speeds=False)
    res = diagnose(path, write=False)
    status = {c["effect"]: c["status"] for c in res["candidates"]}
    assert status["cornering"] == "untestable"
    assert res["findings"] == []          # mixed_lubrication looks the same: ambiguous, not claimed
    assert any("cornering" in a["effects"] for a in res["ambiguities"])


def test_missing_ambient_oil_warmup_untestable_not_misnamed(tmp_path):
    rec, path = _case(tmp_path, ["oil_warmup"], 15, ambient_column=False)
    res = diagnose(path, write=False)
    status = {c["effect"]: c["status"] for c in res["candidates"]}
    assert status["oil_warmup"] == "untestable"
    assert res["findings"] == []
    assert any("oil_warmup" in a["effects"] for a in res["ambiguities"])


def test_no_standstill_preload_is_ambiguous_with_offset(tmp_path):
    rec, path = _case(tmp_path, ["bearing_preload"], 16)
    df = pd.read_csv(path)
    moving = df["diff_input_speed_rpm"].abs() >= 5
    df = df[moving].reset_index(drop=True)
    df["time_s"] = np.arange(len(df)) * 0.1   # splice the driving parts together
    df.to_csv(path, index=False)
    res = diagnose(path, write=False)
    assert res["findings"] == []
    assert any("sensor_offset" in a["effects"] for a in res["ambiguities"])


# ----------------------------------------------------------------------------- acceptance rates
@pytest.mark.slow
@pytest.mark.parametrize("effect", DIFF_EFFECTS)
def test_rate_single_effect(tmp_path, effect):
    ok = sum(_single_ok(rec, diagnose(p, write=False))
             for rec, p in (_case(tmp_path, [effect], seed) for seed in range(10)))
    assert ok >= 9, f"{effect}: {ok}/10"


@pytest.mark.slow
def test_rate_two_effects(tmp_path):
    ok = 0
    for seed in range(10):
        pair = list(np.random.default_rng(seed).choice(PAIR_EFFECTS, 2, replace=False))
        rec, p = _case(tmp_path, pair, 100 + seed)
        ok += set(pair) <= {f["effect"] for f in diagnose(p, write=False)["findings"]}
    assert ok >= 8, f"{ok}/10"


@pytest.mark.slow
def test_rate_noise_only(tmp_path):
    results = [diagnose(_case(tmp_path, [], 200 + seed)[1], write=False) for seed in range(20)]
    ok = sum(r["findings"] == [] for r in results)
    assert ok >= 19, f"{ok}/20"
    # the mismatch itself (selection or drivers) is called significant at most once in 20
    quiet = sum(not r["mismatch"]["significant"] for r in results)
    assert quiet >= 19, f"{quiet}/20"


@pytest.mark.slow
@pytest.mark.parametrize("effect,kw", [("cornering", {"wheel_speeds": False}),
                                       ("oil_warmup", {"ambient_column": False})])
def test_rate_untestable_never_misnamed(tmp_path, effect, kw):
    for seed in range(10):
        res = diagnose(_case(tmp_path, [effect], 300 + seed, **kw)[1], write=False)
        status = {c["effect"]: c["status"] for c in res["candidates"]}
        assert status[effect] == "untestable"
        assert res["findings"] == [], res["findings"]


@pytest.mark.slow
def test_benchmark_one_hour_10hz_under_60s(tmp_path):
    import time

    rec = random_case(["oil_warmup", "cornering"], 7, duration_s=3600.0, rate_hz=10.0)
    path = rec.write(tmp_path / "hour.csv")
    t0 = time.perf_counter()
    res = diagnose(path, out=tmp_path / "out")
    assert time.perf_counter() - t0 < 60.0
    assert {"oil_warmup", "cornering"} <= {f["effect"] for f in res["findings"]}


def test_oil_warmup_with_measured_oil_temperature(tmp_path):
    # with oil_temp_C the loss follows the thermometer; tau_s is fitted to the sump trace
    rec, path = _case(tmp_path, ["oil_warmup"], 17, oil_temp_column=True)
    res = diagnose(path, write=False)
    assert _single_ok(rec, res), (rec.truth["effects"], res["findings"])
    assert any(d["channel"] == "temperature" for d in res["mismatch"]["drivers"])


def test_confounded_candidates_separated_by_their_own_channel(tmp_path):
    # turns happen at intersections, at low speed: on its own, mixed_lubrication (low-speed
    # friction) explains part of a cornering loss; the wheel-speed channel settles it
    rec, path = _case(tmp_path, ["cornering"], 18)
    res = diagnose(path, write=False)
    cand = {c["effect"]: c for c in res["candidates"]}
    assert cand["mixed_lubrication"]["heldout_gain_vs_baseline"] > 0.05
    assert [f["effect"] for f in res["findings"]] == ["cornering"]
    assert cand["mixed_lubrication"]["status"] == "rejected" and res["ambiguities"] == []


def test_heavy_duty_two_speed_low_range(tmp_path):
    # any configuration: a two-speed HD axle in its low range (overall ratio 4.1 x 1.36)
    from fleetrun.testing.recordings import RigSpec, generate_differential_recording

    rig = RigSpec(configuration="HD_DUAL", gear_ratio=4.1, low_gear_ratio=1.36, axle_gear="low",
                  peak_engine_torque_Nm=2000.0, torque_converter_ratio=1.0,
                  max_transmission_gear_ratio=12.8, lubricant="80W90", mass_kg=30000.0,
                  wheel_radius_m=0.5, road_load_N=(2500.0, 40.0, 4.0))
    rec = generate_differential_recording([("bearing_preload", {"drag_torque_Nm": 15.0})], rig=rig,
                                          seed=3, noise_out_Nm=5.0, duration_s=900)
    res = diagnose(rec.write(tmp_path / "hd.csv"), write=False)
    assert [f["effect"] for f in res["findings"]] == ["bearing_preload"]
    assert res["findings"][0]["parameters"]["drag_torque_Nm"] == pytest.approx(15.0, rel=0.1)
    assert res["baseline"]["overall_ratio"] == pytest.approx(4.1 * 1.36)
