"""Where the state gasoline error comes from, and the turnover mpg change against the same
period's published on-road change (validation/gasoline_by_year.py;
docs/validation-state-fuel.md, "Where the state gasoline error comes from").

The published numbers: FHWA VM-1 passenger-car and other 2-axle 4-tire vehicle on-road mpg as
BTS Transportation Statistics Annual Reports 2006 (Table E-9) and 2010 (Table 5-9) tabulate them;
the nation's highway gasoline and vehicle-miles as the sums of the 51 states of BTS State
Transportation Statistics (MF-21, VM-2), which must equal FHWA's national totals of 2000
(NTS Table 4-9 miles, MF-21 gasoline in ``national_years.csv``).
"""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _module():
    sys.path.insert(0, str(ROOT / "validation"))
    import gasoline_by_year

    return gasoline_by_year


def test_sum_of_the_states_is_the_national_total_of_2000():
    """Two independent tabulations: the 51 states' BTS series summed against FHWA's U.S.
    totals of 2000 (rounded to the million gallons / million miles there)."""
    module = _module()
    national = pd.read_csv(ROOT / "inputs" / "state_statistics" / "national_years.csv").set_index("year")
    summed = module.national()
    assert summed.highway_gasoline_kgal[2000] / 1e3 == pytest.approx(national.highway_gasoline_mgal[2000], abs=0.5)
    assert summed.vmt_million_mi[2000] == pytest.approx(national.vmt_million_mi[2000], abs=0.5)


def test_published_vm1_change_2000_2001():
    """VM-1 2000 -> 2001: passenger cars 21.9 -> 22.1 mpg, other 2-axle 4-tire vehicles
    17.4 -> 17.6 mpg (TSAR 2006 Table E-9): +0.91 and +1.15 %/yr."""
    change = _module().published_change(2000, 2001)
    assert change["vm1_low"] == pytest.approx(100 * (22.1 / 21.9 - 1), abs=1e-9)
    assert change["vm1_high"] == pytest.approx(100 * (17.6 / 17.4 - 1), abs=1e-9)


def test_turnover_against_the_same_period():
    """What the docs report from the saved runs: the model's light-duty mpg change falls below
    VM-1's range of the same calendar years from 2000 and 2003, and inside it from 2006; no VM-1
    light-duty mpg of the later periods is shipped, so they are not judged."""
    table = _module().turnover_by_period(pd.read_csv(ROOT / "docs" / "validation-state-fuel.csv"))
    table = table.set_index(["start", "end"])
    for period in ((2000, 2001), (2003, 2004)):
        row = table.loc[period]
        assert row.model_high < row.vm1_low and row.in_vm1_range == 0, period
    row = table.loc[(2006, 2007)]
    assert row.in_vm1_range == row.state_years
    assert table.loc[(2010, 2011)].vm1_low != table.loc[(2010, 2011)].vm1_low   # NaN: not judged


@pytest.mark.slow
def test_sum_of_state_runs_is_the_national_run_2010():
    """The 51 state runs of 2010 add up to the national run of the same workbook within 0.1 %
    (the model is additive over states; registrations barely move gallons per mile once VMT is
    given), so the VMT-weighted state error equals the national error, measured +6.6 % against
    the states' summed MF-21 gasoline: above the nation of 2000 (+3.2 %, within the issue's 5 %;
    docs/validation-state-fuel.md part 2)."""
    module = _module()
    nation = module.national_runs()
    states = module.all_states_runs(years=(2010,))
    summary = module.sum_of_states(states, nation).set_index("year").loc[2010]
    assert abs(summary.states_vs_national_run_pct) <= 0.1
    error_2000 = nation.set_index("year").gasoline_error_pct[2000]
    assert abs(error_2000) <= 5.0
    assert summary.national_error_pct > error_2000 + 2.0
