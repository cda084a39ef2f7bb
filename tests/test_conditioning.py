"""sicomat.mechanics.conditioning: models whose numbers double precision cannot carry are refused, by name."""

from __future__ import annotations

import math

import pytest
from numpy.testing import assert_allclose

from sicomat import ChainSpec, build_mechanics, modal_analysis
from sicomat.mechanics.conditioning import check_numeric_range
from sicomat.errors import AnalysisError, ModelError


def _chain(k_stiff: float):
    # 1 kg -k_stiff- 2 kg -1e7 N/m, 10 N*s/m- 3 kg (and 10 N*s/m on the stiff link)
    return build_mechanics(ChainSpec(type="chain", masses=[1, 2, 3], stiffnesses=[k_stiff, 1e7],
                                     dampings=[10, 10]))


def test_a_1e30_spring_beside_1e7_is_refused_naming_the_couplings():
    # before: a damped frequency of 290.6 Hz for the 410.9 Hz mode (a rigid pole taken for it)
    with pytest.raises(ModelError, match="couplings 'k1' and 'k2' differ too much") as info:
        modal_analysis(_chain(1e30))
    assert info.value.path == "mechanics.couplings.k1.stiffness"


def test_a_resolvable_spread_keeps_its_soft_mode():
    # 1e16 N/m: the pole error bound of the soft mode is 2e-7 of the pole (kappa * eps * |A|), and
    # the stiff link differs from a rigid one by k_soft/k_stiff = 1e-9: the soft mode is that of
    # 3 kg (1 + 2 kg rigidly joined) -1e7 N/m, 10 N*s/m- 3 kg to within 1e-6.
    res = modal_analysis(_chain(1e16))
    soft = [m for m in res.modes if not m.rigid][0]
    mu, k, c = 1.5, 1e7, 10.0                       # reduced mass of 3 kg and 3 kg
    # 1e-6: five times the pole bound (2e-7) and 1e3 times the rigid-link approximation (1e-9), above
    assert_allclose(soft.frequency_hz, math.sqrt(k / mu) / (2 * math.pi), rtol=1e-6)
    assert_allclose(soft.damping_ratio, c / (2 * math.sqrt(k * mu)), rtol=1e-6)


@pytest.mark.parametrize("values, key", [({"bodies.a.mass": 1e300, "couplings.k.stiffness": 1e7}, "bodies.a.mass"),
                                         ({"bodies.a.mass": 1.0, "couplings.k.stiffness": 1e-120},
                                          "couplings.k.stiffness")])
def test_values_outside_the_double_precision_range_are_refused(values, key):
    # (a file never gets here: sicomat.description.units refuses such magnitudes as it reads them)
    with pytest.raises(ModelError, match="in double precision") as info:
        check_numeric_range(values)
    assert info.value.path == f"mechanics.{key}"


def test_a_negative_damping_ratio_is_never_reported():
    from sicomat.mechanics.modal import Mode, _check_passive

    good = Mode(frequency_hz=80.0, damping_ratio=0.01, damped_frequency_hz=79.99, undamped_hz=80.0,
                shape={"a": 1.0}, rigid=False)
    _check_passive([good])
    for bad in (good.__class__(**{**good.__dict__, "damping_ratio": -0.02}),
                good.__class__(**{**good.__dict__, "frequency_hz": float("nan")})):
        with pytest.raises(AnalysisError, match="not resolved"):
            _check_passive([bad])
