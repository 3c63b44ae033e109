"""The model files in models/ and their evaluator: documented data, safe arithmetic, clear errors."""
import pytest

from fleetrun.differential.expressions import evaluate
from fleetrun.differential.models import configuration_table, reference_model, reference_models
from fleetrun.errors import InputError


def test_every_geometry_entry_has_unit_and_source():
    for model in reference_models().values():
        for key, spec in model.geometry.items():
            assert "unit" in spec and spec.get("source"), (model.id, key)


def test_every_configuration_resolves_to_known_models():
    for config, spec in configuration_table().items():
        for chain in spec["factors"]:
            for model_id in chain:
                assert reference_model(model_id).id == model_id, config


def test_scaling_rules_follow_appendix_b2():
    # B.2: pinion radii grow as G/g below the measured 41/12; ring face width as g/G above
    model = reference_model("gm_1500_rear_axle")
    low, ref, high = model.resolve(2.5), model.resolve(41 / 12), model.resolve(5.0)
    assert low["r_p_p"] == pytest.approx(ref["r_p_p"] * (41 / 12) / 2.5, rel=1e-15)
    assert high["r_p_p"] == ref["r_p_p"]
    assert high["l_fw_g"] == pytest.approx(ref["l_fw_g"] * 5.0 / (41 / 12), rel=1e-15)
    assert low["l_fw_g"] == ref["l_fw_g"]


def test_evaluator_arithmetic_and_conditionals():
    assert evaluate("x*G/g if g < G else x", {"x": 2.0, "G": 4.0, "g": 2.0}) == 4.0
    assert evaluate("acos(1.75/2.9375)", {}) == pytest.approx(0.93263, rel=1e-4)
    assert evaluate(3, {}) == 3.0


@pytest.mark.parametrize("text", ["__import__('os').system('true')", "open('x')", "x.real", "[1][0]", "lambda: 1"])
def test_evaluator_refuses_anything_but_arithmetic(text):
    with pytest.raises(InputError):
        evaluate(text, {"x": 1.0}, where="test.toml [geometry] k")


def test_unknown_name_error_names_the_place():
    with pytest.raises(InputError) as err:
        evaluate("r_q*2", {"r_p": 1.0}, where="axle.toml [derived] r_p_g")
    assert "axle.toml [derived] r_p_g" in str(err.value) and "r_p" in str(err.value)


def test_effects_and_physics_share_one_registry_mechanism():
    from fleetrun.effects import get_effect
    from fleetrun.registry import EFFECTS, PHYSICS

    import fleetrun.differential  # noqa: F401  (registers the baselines)

    assert get_effect("Bearing-Preload") is EFFECTS["bearing_preload"]
    for registry, wrong, near in ((EFFECTS, "cornerring", "cornering"), (PHYSICS, "vecto", "vecto-generic")):
        with pytest.raises(InputError) as err:
            registry.get(wrong)
        assert f"did you mean '{near}'" in str(err.value)
        assert all(name in str(err.value) for name in registry.names())
