"""The ``greybox`` model family on a building: the one-state network fitted by maximum likelihood, predicting the
indoor temperature from the inputs only (the conformance suite checks the contract on machine-tool data)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from benchmarks.independent import house_sde
from thermodrift.core import registry
from thermodrift.core.metrics import rmse

ROLES = {"Ta": "ambient", "Ps": "solar_irradiance", "Thm": "heating"}


def _frames(days: float, seed: int):
    house = house_sde.draw_house("Ti", np.random.default_rng(seed))
    house.params["sigma_i"] = 0.01                     # nearly deterministic: the fit must find the truth
    df = house_sde.simulate(house, days=days, seed=seed)
    X = df[list(ROLES)].set_index(pd.Index(np.arange(len(df)) * 900.0, name="time_s"))
    X.attrs["roles"] = dict(ROLES)
    y = pd.DataFrame({"yTi": df["yTi"].to_numpy()}, index=X.index)
    return house, X, y


@pytest.fixture(scope="module")
def fitted():
    house, X, y = _frames(18.0, 4)
    cut = 15 * 96                                      # the simulation starts cold: 8 time constants of history
    model = registry.default().get("model", "greybox").factory(structure="Ti", starts=1)
    model.fit(X.iloc[:cut], y.iloc[:cut])
    return house, X, y, cut, model


def test_building_inputs_take_the_building_network(fitted):
    _, _, _, _, model = fitted
    assert model.building_ and model.structures_ == ["Ti"]


def test_held_out_days_predicted_from_inputs_only(fitted):
    house, X, y, cut, model = fitted
    pred = model.predict(X.iloc[cut:], history=X.iloc[:cut])[:, 0]
    truth = y.iloc[cut:, 0].to_numpy()
    assert rmse(pred, truth) < 0.1                     # K: the true network, almost no process noise
    assert rmse(pred, truth) < 0.2 * float(np.std(truth))
    # the fitted steady heat loss is the true HTC: 1 kW more for ever warms the house by 1 / HTC
    system = model.systems_[0]
    gain = system.static_gain()[0, 2]
    assert gain == pytest.approx(1.0 / house.htc, rel=0.1)


def test_no_measured_target_is_read(fitted):
    """The same inputs give the same prediction whatever the indoor temperature did."""
    _, X, _, cut, model = fitted
    a = model.predict(X.iloc[cut:], history=X.iloc[:cut])
    b = model.predict(X)[cut:]
    assert np.allclose(a, b, atol=1e-9)
