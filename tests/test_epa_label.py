"""EPA's derived 5-cycle label formulas and their coefficient sets by model year
(fleetrun/physics/epa_label.py; models/budget.toml [onroad.epa_label.sets]; docs/budget.md)."""
from __future__ import annotations

import numpy as np
import pytest

from fleetrun.errors import InputError
from fleetrun.physics import epa_label


@pytest.mark.parametrize(("model_year", "name"), [
    (2008, "derived_2008"), (2016, "derived_2008"), (2017, "derived_2017"), (2022, "derived_2017"),
    (1995, "derived_2008"),      # before every set: the oldest
    (None, "derived_2017"), (float("nan"), "derived_2017"),   # no model year: a current vehicle
])
def test_the_model_year_chooses_the_set(model_year, name):
    """EPA's labels change coefficients at MY2017 (NREL FASTSim applies "2008" to veh_year < 2017,
    "2017" from then; rust/fastsim-core/src/simdrivelabel.rs)."""
    assert epa_label.set_for_model_year(model_year).name == name


def test_an_unknown_set_name_lists_the_valid_ones():
    with pytest.raises(InputError, match="derived_2017"):
        epa_label.label_set("derived_2071")


def test_the_my2017_set_reproduces_a_published_label():
    """fueleconomy.gov MY2022 Toyota Camry 3.5 L, label id 44343 (inputs/fueleconomy/
    vehicles_my2022.csv): unadjusted UCity 28.6, UHighway 47.8 mpg; published unrounded label
    city08U 22.3944, highway08U 33.0332, comb08U 26.1901 mpg. The database prints four decimals:
    tolerance 5e-6 relative. The 2008 set misses the city figure by 0.3 %."""
    s = epa_label.set_for_model_year(2022)
    city = 1.0 / epa_label.label_gal_per_mile(1.0 / 28.6, *s.city)
    highway = 1.0 / epa_label.label_gal_per_mile(1.0 / 47.8, *s.highway)
    assert city == pytest.approx(22.3944, rel=5e-6) and highway == pytest.approx(33.0332, rel=5e-6)
    assert epa_label.combined_label_mpg(28.6, 47.8, s) == pytest.approx(26.1901, rel=5e-6)
    old = epa_label.label_set("derived_2008")
    assert abs(1.0 / epa_label.label_gal_per_mile(1.0 / 28.6, *old.city) / 22.3944 - 1.0) > 0.002


def test_coefficients_per_vehicle_follow_each_model_year():
    a, b = epa_label.coefficients([2010, 2020, None], "highway")
    assert a.tolist() == [0.001376, 0.003191, 0.003191] and b.tolist() == [1.3466, 1.2945, 1.2945]
    assert np.all(np.diff([s.first_model_year for s in epa_label.label_sets().values()]) > 0)
