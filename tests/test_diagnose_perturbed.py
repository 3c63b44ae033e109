"""Issue 16, done when: on rig recordings whose true forms are close to the catalogue's but not
the same (fleetrun.testing.recordings.PERTURBED_FORMS), AR(1) noise with a random coefficient,
>= 10 seeds per case (validation/diagnose_perturbed.py builds and scores them):

* single effects named first >= 95 %, parameters within 25 % (the issue's tolerance),
  held-out error halved or at the noise floor;
* pairs both named >= 90 %; noise only quiet >= 95 %; untestable effects never named;
* ``unexplained.significant`` false in >= 90 % of the in-catalogue recordings and true in
  >= 90 % of those with a cause outside the catalogue (including an output-transducer gain
  drift, which the sensor_drift check must also flag).

The table these shares come from is in docs/diagnose.md; all cases run once per session.
"""
import pytest

from validation.diagnose_perturbed import run, shares

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    return shares(run(10, tmp_path_factory.mktemp("perturbed")))


def _share(table, name):
    hit, n = table[name]
    return hit / n


@pytest.mark.parametrize("name,least", [
    ("single effect named first", 0.95),
    ("single: parameters within 25 %", 0.95),
    ("single: held-out error halved or at the noise floor", 0.95),
    ("pair: both named", 0.90),
    ("noise only: no finding", 0.95),
    ("untestable: no finding", 1.0),
    ("in catalogue: unexplained.significant false", 0.90),
    ("outside the catalogue: unexplained.significant true", 0.90),
    ("gain drift: sensor_drift fires", 0.90),
])
def test_share(table, name, least):
    assert _share(table, name) >= least, table[name]
