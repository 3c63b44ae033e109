"""Several recordings of one vehicle diagnosed together (fleetrun.diagnose.joint).

Generated problems with a known answer: two recordings whose residual is the same effect at
the same size (a vehicle property) plus white noise, and a warm-up in only one of them (a
condition of that recording). The joint selection must recover the shared size (within the
noise's 3 standard errors) and give the warm-up to the recording that has it.
"""
import numpy as np
import pytest

from fleetrun.diagnose.engine import IntegralSpec, Problem, Settings, select
from fleetrun.diagnose.joint import join
from fleetrun.diagnose.select import Candidate, effect_of
from fleetrun.errors import InputError

N = 700
TAUS = [30.0, 60.0, 120.0, 240.0]


def _problem(seed: int, grade_signal: float, warm: float, speed_scale: float) -> Problem:
    rng = np.random.default_rng(seed)
    t = np.arange(N, dtype=float)
    speed = speed_scale * (1 + np.sin(2 * np.pi * t / 170.0)) * (rng.random(N) > 0.1)
    grade_col, drag_col = 0.01 * speed, 1e-4 * speed ** 3
    warm_cols = [np.exp(-t / tau) for tau in TAUS]
    residual = grade_signal * grade_col + warm * warm_cols[1] + rng.normal(0.0, 0.02, N)
    cands = [Candidate("warmup", warm_cols, [{"tau_s": tau} for tau in TAUS], 0.0, 20.0,
                       column_for=lambda sh, t=t: np.exp(-t / sh["tau_s"]), shape_bounds=(20.0, 600.0)),
             Candidate("road_grade", [grade_col], [{}], -15.0, 15.0),
             Candidate("aero_drag", [drag_col], [{}], 0.0, 5.0)]
    return Problem("vehicle", "fuel_rate_g_per_s", t, residual, np.zeros(N), cands, {},
                   driver_channels={"speed": speed}, units="g/s",
                   initial_terms=[(np.ones(N), -0.01, 0.01)],
                   integral=IntegralSpec(moving=speed > 0.1, speed_mps=speed, weight=np.ones(N), unit="g"))


def test_a_shared_effect_and_a_per_recording_warmup():
    # grade 0.5 % in both recordings (a city-like and a highway-like speed), warm-up only in
    # the first
    a, b = _problem(1, 0.5, 0.4, 5.0), _problem(2, 0.5, 0.0, 15.0)
    joined, pieces = join([a, b], ["city", "highway"])
    assert [c.id for c in joined.candidates] == ["warmup@city", "warmup@highway", "road_grade", "aero_drag"]
    assert [(p.start, p.stop) for p in pieces] == [(0, N), (N, 2 * N)]
    # a per-recording column is zero on the other recording; a shared one is both columns
    assert not joined.candidates[0].columns[0][N:].any() and not joined.candidates[1].columns[0][:N].any()
    assert np.array_equal(joined.candidates[2].columns[0][N:], b.candidates[1].columns[0])
    assert np.all(np.diff(joined.time_s) > 0)
    sel = select(joined, Settings(n_shifts=50))
    found = {f.effect: f.parameters for f in sel.findings}
    assert set(found) == {"road_grade", "warmup@city"}
    # 3 standard errors of a least-squares grade on 1400 samples of noise 0.02 g/s
    x = joined.candidates[2].columns[0]
    se = 0.02 / np.sqrt(x @ x)
    assert abs(found["road_grade"]["grade_pct"] - 0.5) < 3 * se + 1e-3
    assert effect_of("warmup@city") == "warmup" and effect_of("road_grade") == "road_grade"


def test_the_calibration_terms_stay_each_recordings_own():
    a, b = _problem(3, 0.0, 0.0, 5.0), _problem(4, 0.0, 0.0, 9.0)
    joined, _ = join([a, b], ["one", "two"])
    (c1, _, _), (c2, _, _) = joined.initial_terms
    assert np.array_equal(c1, np.r_[np.ones(N), np.zeros(N)])
    assert np.array_equal(c2, np.r_[np.zeros(N), np.ones(N)])


def test_join_refuses_one_recording_and_mixed_levels():
    a = _problem(5, 0.0, 0.0, 5.0)
    with pytest.raises(InputError):
        join([a], ["one"])
    other = _problem(6, 0.0, 0.0, 5.0)
    other.level = "differential"
    with pytest.raises(InputError):
        join([a, other], ["one", "two"])


@pytest.mark.slow
def test_real_camry_three_cycles_with_a_same_trace_reference_each():
    """Design J2 of validation/diagnose_concealed_joint.py (docs/diagnose-realdata.md, 1c):
    the clean targets name only the real cold start, in the recording that has it; every
    concealed effect that is named is sized within 25 %; the drag at C + 60 % is named.
    (The floor measured: 1 of 6 cases meets all three criteria; the issue asks for 6.)"""
    from validation.diagnose_concealed_joint import run

    clean, cases = run("J2")
    assert [f["effect"] for f in clean["findings"]] == ["warmup@camry2018_udds_cold"]
    assert all(c.size_ok for c in cases if c.named)
    drag = next(c for c in cases if c.effect == "aero_drag" and c.size == 0.6)
    assert drag.named and drag.size_ok and drag.phases_ok


@pytest.mark.slow
def test_real_camry_warm_runs_noise_weighted():
    """Designs W (pre-registered) and Wh (after W) of validation/diagnose_concealed_joint.py
    (docs/diagnose-realdata.md, 1d): warm runs, noise-weighted windows. The clean targets
    name nothing; every named effect is sized within 25 %; measured floors: W meets all three
    criteria in 2 of 6 cases (the drag at both sizes), Wh (every target declared a hot start)
    in 4 of 6 (the accessory load at both sizes as well). The issue asks for 6."""
    from validation.diagnose_concealed_joint import run

    for design, floor in (("W", 2), ("Wh", 4)):
        clean, cases = run(design)
        assert clean["findings"] == []
        assert all(c.size_ok for c in cases if c.named)
        assert sum(c.named and c.size_ok and c.phases_ok for c in cases) >= floor
        assert all(c.named for c in cases if c.effect == "aero_drag")


@pytest.mark.slow
def test_real_camry_grade_located_along_the_route():
    """Designs G and R of validation/diagnose_concealed_joint.py (docs/diagnose-realdata.md,
    1e, both pre-registered): with a grade profile per target (G) the clean targets name
    nothing, no profile is named where a drag or an accessory load was concealed, every named
    effect is sized within 25 %, and the measured floor holds (3 of 6); a real road's grade
    concealed (R) is never taken for a drag or an accessory load."""
    from validation.diagnose_concealed_joint import ROUTE_SIZES, run

    clean, cases = run("G")
    assert clean["findings"] == []
    assert all(c.size_ok for c in cases if c.named)
    assert sum(c.named and c.size_ok and c.phases_ok for c in cases) >= 3
    assert not any(f.startswith("road_grade") for c in cases if c.effect != "road_grade" for f in c.findings)
    for design in ("Wh", "G"):
        _, route = run(design, sizes=ROUTE_SIZES)
        assert all(set(c.findings) <= {"road_grade"} for c in route)


@pytest.mark.slow
def test_real_camry_one_road_under_every_target():
    """Design L of validation/diagnose_concealed_joint.py (docs/diagnose-realdata.md, 1f,
    pre-registered): one road under every target (a block candidate). The clean targets name
    nothing; the road is never named where a drag or an accessory load was concealed; the six
    cases keep Wh's floor (4 of 6); the EPA road driven the other way (not looked at before
    the design was fixed) is named at both sizes, and every named road's raw fuel moved is
    within 25 % of the concealed (measured -24 to +2 %)."""
    from validation.diagnose_concealed_joint import L_SIZES, MOVED, run

    clean, cases = run("L", sizes=L_SIZES)
    assert clean["findings"] == []
    six = [c for c in cases if c.effect not in MOVED]
    assert sum(c.named and c.size_ok and c.phases_ok for c in six) >= 4
    assert not any(f == "road_grade" for c in six if c.effect != "road_grade" for f in c.findings)
    roads = [c for c in cases if c.effect in MOVED]
    assert all(c.named for c in roads if c.effect == "road_profile_reversed")
    assert all(abs(c.fitted_raw_g / c.concealed_g - 1) <= 0.25 for c in roads if c.named)


@pytest.mark.slow
def test_real_camry_road_sized_after_its_selection():
    """Designs Lr and Lr5 of validation/diagnose_concealed_joint.py (docs/diagnose-realdata.md,
    1g-1h, pre-registered): L with a named road's knots refitted, the penalty relaxed by
    held-out error. Named-ness is L's (clean targets quiet, no road for a concealed drag or
    accessory load, the six at 4 of 6). Lr (1-km knots) sizes the road within 25 % in 1 of 3
    named cases (measured -36 / -23 / -26 %); Lr5 (500-m knots, now the library's default) in
    all three (-24 / -11 / -10 %), the f = 1.0 road meeting all three criteria. A road fitted
    with no noise by 1-km knots already moves 10-21 % less fuel than the concealed one
    (``knot_ceiling``), which is why Lr cannot reach it."""
    from validation.diagnose_concealed_joint import L_SIZES, MOVED, knot_ceiling, run

    for design, sized in (("Lr", 1), ("Lr5", 3)):
        clean, cases = run(design, sizes=L_SIZES)
        assert clean["findings"] == [] and clean["road_background_factor"] == 1.0
        six = [c for c in cases if c.effect not in MOVED]
        assert sum(c.named and c.size_ok and c.phases_ok for c in six) >= 4
        assert not any(f == "road_grade" for c in six if c.effect != "road_grade" for f in c.findings)
        roads = [c for c in cases if c.effect in MOVED]
        assert [c.named for c in roads] == [False, True, True, True]
        assert sum(c.size_ok for c in roads) >= sized
        # the refit never leaves a named road's phase-fuel error above L's (17.3 / 19.3 / 42.9 g)
        assert all(c.phase_error_after_g < c.phase_error_before_g for c in roads if c.named)
    f1 = next(c for c in roads if c.effect == "road_profile" and c.size == 1.0)
    assert f1.size_ok and f1.phases_ok
    ceiling = {(e, s): v for e, s, _, v, _ in knot_ceiling(spacings=(1000.0, 500.0))}
    assert all(-0.25 < v[1000.0] < -0.09 and v[1000.0] < v[500.0] < 0 for v in ceiling.values())


def test_join_refuses_two_recordings_of_one_name():
    with pytest.raises(InputError, match="distinct"):
        join([_problem(7, 0.0, 0.0, 5.0), _problem(8, 0.0, 0.0, 5.0)], ["run", "run"])
