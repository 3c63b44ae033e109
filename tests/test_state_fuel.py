"""The registrations validation on a state no fit used (docs/validation-state-fuel.md):
Colorado 2014 from its FHWA MV-1 counts and VM-2 miles only, uncalibrated, against MF-27
highway gasoline (the issue's 5 % target, met there as the page reports); calibrated on 2014,
2016 gasoline from 2016's VMT (VM-3M) closer to MF-21 than gallons proportional to VMT; the
light-duty fleet's mpg change inside the published range (FHWA VM-1 all vehicles 1990-2002 to
EPA Trends new vehicles 2004-2022)."""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_colorado_2014_from_registrations_only():
    sys.path.insert(0, str(ROOT / "validation"))
    import state_fuel

    table = state_fuel.main(["--states", "Colorado"])
    row = table.iloc[0]
    data = pd.read_csv(state_fuel.DATA)
    observed = data[(data.state == "Colorado") & (data.year == 2014)].iloc[0]
    assert row.gasoline_observed_Mgal == pytest.approx(observed.highway_gasoline_kgal / 1e3)
    assert abs(row.gasoline_error_pct) <= 100 * state_fuel.GASOLINE_TOLERANCE
    assert abs(row.gasoline_forecast_error_pct) < abs(row.gasoline_naive_error_pct)
    low, high = state_fuel.PUBLISHED_MPG_CHANGE_PCT
    assert low <= row.ld_mpg_change_pct_per_year <= high
