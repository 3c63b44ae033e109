"""The real-data diagnoses of docs/diagnose-realdata.md (and the README) hold.

Camry cold- vs hot-start UDDS: the mismatch is located in the first phase (the cold start)
and attributed to `warmup`; the first bag's fuel error is at least halved. Thesis Sec. 7.2:
with wheel speeds recorded, the low-speed shortfall of the model against Matthews' fit is
described by `mixed_lubrication` at the bound of its friction share (a weak description);
without them it cannot be told from `cornering` and is reported ambiguous, not claimed.
"""
import pytest

from validation.diagnose_realdata import run


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    return run(tmp_path_factory.mktemp("realdata"))


def test_camry_cold_start_is_warmup_in_the_first_phase(results):
    doc = results["camry_cold_vs_hot"]
    assert [f["effect"] for f in doc["findings"]] == ["warmup"]
    assert doc["baseline"]["residual"] == "same_trace"      # the hot run of the same UDDS
    first = doc["mismatch"]["segments"][0]
    assert first["start_s"] < 60 and first["share"] > 0.3      # UDDS phase 1 is 0-505 s
    assert all(seg["end_s"] <= 505 for seg in doc["mismatch"]["segments"][:2])
    finding = doc["findings"][0]
    assert finding["heldout_rmse_after"] < finding["heldout_rmse_before"]
    bag1 = doc["integrals"][0]
    assert (bag1["start_s"], bag1["end_s"], bag1["label"]) == (0.0, 505.0, "UDDS bag 1")
    assert abs(bag1["after"] - bag1["measured"]) <= 0.5 * abs(bag1["before"] - bag1["measured"])


@pytest.mark.parametrize("vehicle", ["ford_f150", "mercedes_300e", "cadillac_deville", "nissan_240sx"])
def test_thesis_sec_7_2_low_speed_loss(results, vehicle):
    # with wheel speeds, the low-speed shortfall is described by mixed lubrication, but its
    # friction share sits at the 0.5 bound (beyond published hypoid friction, as thesis
    # Sec. 7.2 says): a weak description, not a finding
    straight = results[f"matthews_{vehicle}"]
    assert straight["findings"] == []
    desc = {d["effect"]: d for d in straight["descriptions"]}
    assert "mixed_lubrication" in desc and "edge of its plausible range" in desc["mixed_lubrication"]["reason"]
    d = desc["mixed_lubrication"]
    assert d["heldout_rmse_after"] < 0.5 * d["heldout_rmse_before"]
    assert straight["unexplained"]["significant"] is True
    unknown = results[f"matthews_{vehicle}_no_wheel_speeds"]
    assert unknown["findings"] == []
    status = {c["effect"]: c for c in unknown["candidates"]}
    assert status["mixed_lubrication"]["status"] == "ambiguous"
    assert "wheel" in status["mixed_lubrication"]["separating_test"]
    assert status["cornering"]["status"] == "untestable"
    assert status["cornering"]["could_explain"] == "mixed_lubrication"


def test_recording_errors_name_file_row_column_and_key(tmp_path):
    from click.testing import CliRunner

    from fleetrun.cli import cli

    rows = ["time_s,diff_input_torque_Nm,diff_input_speed_rpm,diff_output_torque_Nm"]
    rows += [f"{i},100,1000,300" for i in range(40)]
    rows[5] = "4,abc,1000,300"
    (tmp_path / "r.csv").write_text("\n".join(rows) + "\n")
    sidecar = ('configuration = "{}"\ngear_ratio = 3\npeak_engine_torque_Nm = 300\n'
               'torque_converter_ratio = 3\nmax_transmission_gear_ratio = 4\n')
    (tmp_path / "r.toml").write_text(sidecar.format("LD_RWD"))
    result = CliRunner().invoke(cli, ["diagnose", str(tmp_path / "r.csv"), "--out", str(tmp_path / "d")])
    assert result.exit_code == 1
    assert "r.csv: row 6, column diff_input_torque_Nm: not a number: 'abc'" in result.output
    (tmp_path / "r.toml").write_text(sidecar.format("LD_XYZ"))
    result = CliRunner().invoke(cli, ["diagnose", str(tmp_path / "r.csv"), "--out", str(tmp_path / "d")])
    assert result.exit_code == 1
    assert "r.toml: key configuration: unknown configuration 'LD_XYZ'" in result.output
    assert not (tmp_path / "d").exists()


# ----------------------------------------------------------------------------- concealed physics
@pytest.fixture(scope="module")
def concealed(tmp_path_factory):
    from validation.diagnose_concealed import run as run_concealed

    return run_concealed(tmp_path_factory.mktemp("concealed"))


@pytest.mark.slow
def test_concealed_effects_in_the_real_camry_recording(concealed):
    """Issue 16: physics concealed in the real cold-start UDDS (computed with the simulation,
    2-5 % of its fuel), diagnosed against the real hot-start UDDS. The clean recording says
    only what it already said (the real cold start); a concealed effect that is named is sized
    within 25 % (over what the same effect fits on the clean pair) and never displaces the
    warm-up. Measured (docs/diagnose-realdata.md): 3 of 6 cases named, sized and with the phase
    error at least halved; the switching accessory load and the smaller grade are not named
    (the pair's real 2-5 % run-to-run difference is described as well by a grade, a drag or an
    accessory load). The test holds that floor so that it cannot silently get worse."""
    clean, cases = concealed
    assert [f["effect"] for f in clean["findings"]] == ["warmup"]
    assert clean["unexplained"]["significant"] is False
    for c in cases:
        assert "warmup" in c.findings, c
        if c.named:
            assert c.size_ok, c
    assert sum(c.named and c.size_ok and c.phases_ok for c in cases) >= 3
    assert any(c.named for c in cases if c.effect == "road_grade")
    assert all(c.named for c in cases if c.effect == "aero_drag")


@pytest.mark.slow
def test_why_the_pair_hides_a_small_grade_or_accessory_load(concealed):
    """Issue 16's unmet part, measured (docs/diagnose-realdata.md, "Why ... not named"): on
    the clean pair the run-to-run difference, fitted as a grade, a drag or an accessory load
    alone, is itself beyond noise (> 1.5 standard errors) and at least 70 % of the smaller
    concealed effect's fuel; fitted jointly the three columns are too alike to separate (joint
    standard errors at least 40 % of that fuel); only the cold UDDS's second bag agrees with
    the reference within 1 % while the hot UDDS is 1.5-6 % above it, of which the two runs'
    speed traces explain under 1 point (the simulation on each run's own trace); weighting
    the windows by their inverse noise variance (idle's lower noise) leaves the difference as
    large (39-54 g). Bounds are the measured values (41.5/28.9/32.9 g, se 13.2/8.3/18.7 alone, 35.0/17.0/29.8 jointly;
    -0.42 %, +2.02 %, +4.75 %) with room for the run-to-run changes of the code around them."""
    from validation.diagnose_concealed import separation

    _, cases = concealed
    sep = separation()
    smallest = {c.effect: min(x.concealed_g for x in cases if x.effect == c.effect) for c in cases}
    for e in sep.effects:
        assert e.clean_alone_g > 1.5 * e.alone_se_g, e
        assert e.clean_alone_g > 0.7 * smallest[e.effect], e
        assert e.joint_se_g > 0.4 * smallest[e.effect], e
    for e in sep.weighted:      # idle's lower noise does not change it (noise-weighted windows)
        assert e.clean_alone_g > 1.5 * e.alone_se_g and e.clean_alone_g > 0.7 * smallest[e.effect], e
    cos = {(a, b): c for a, b, c in sep.cosines}
    assert cos[("road_grade", "aero_drag")] > 0.8
    bags = {b.label: b for b in sep.bags}
    assert abs(bags["cold UDDS bag 2"].measured_pct) < 1.0
    assert all(1.5 < bags[k].measured_pct < 6.0 for k in ("hot UDDS bag 1", "hot UDDS bag 2"))
    assert all(abs(b.trace_pct) < 1.0 for b in sep.bags)
