"""Models ``lptn`` and ``lptn_hybrid``: shapes, continuation of the physics, the hybrid's correction, configs."""

import pickle

import numpy as np
import pandas as pd
import pytest

from thermodrift.core import configs, physics, registry
from thermodrift.core.physics import scenarios
from thermodrift.core.physics.calibration import StateObserver
from thermodrift.core.physics.scenarios import Block
from thermodrift.core.physics.synthetic import synthesize
from thermodrift.plugins.models.lptn import LPTN, LPTNHybrid, input_roles

CHEAP = {"hidden_nodes": 1, "max_evaluations": 50}

# A spindle node heated by the speed and a column node that follows the room's daily cycle; the drift reads both.
SPEC = {
    "name": "spindle_and_column", "reference_speed_rpm": 6000,
    "nodes": {"spindle": {"capacity_J_K": 1e4, "group": "bearing"},
              "column": {"capacity_J_K": 5e4, "group": "structure"}},
    "edges": [{"a": "spindle", "b": "ambient", "G_W_K": 4.0, "kind": "convection"},
              {"a": "column", "b": "ambient", "G_W_K": 20.0, "kind": "convection"}],
    "sources": {"bearing": {"type": "bearing", "node": "spindle", "viscous_W": 50.0}},
    "outputs": {"z": {"axis": "z", "sensitivity_um_K": {"spindle": 2.0, "column": 4.0}},
                "x": {"axis": "x", "sensitivity_um_K": {"spindle": -1.0}}},
    "sensors": {"T_spindle": {"node": "spindle", "noise_K": 0.01}, "T_column": {"node": "column", "noise_K": 0.01},
                "disp_z": {"output": "z", "noise_um": 0.05}, "disp_x": {"output": "x", "noise_um": 0.05}},
}


@pytest.fixture(scope="module")
def frames():
    """24 h of speed blocks in a room swinging 17–27 °C that the recording does not measure."""
    net = physics.network_from_dict(SPEC)
    prog = [Block(0.5)] + [b for n in (2000, 5000, 3500, 6000, 1000, 4000) for b in (Block(2.5, n), Block(1.5))]
    scen = scenarios.blocks(prog, 60.0, ambient=scenarios.daily_cycle(17.0, 27.0))
    rec = synthesize(net, scen, 0).recording
    assert not rec.columns("ambient")
    X = rec.data[["T_spindle", "T_column", "spindle_rpm"]]
    X.attrs["roles"] = {c: rec.channels[c].role for c in X.columns}  # as the study passes them
    y = rec.data[["disp_z", "disp_x"]]
    cut = int(np.searchsorted(rec.time_s, 16 * 3600.0))
    return X, y, cut


def test_fit_predict_shapes_for_one_and_two_channels(frames):
    X, y, cut = frames
    for cls in (LPTN, LPTNHybrid):
        for targets in (y, y[["disp_z"]]):
            model = cls(**CHEAP)
            assert model.fit(X.iloc[:cut], targets.iloc[:cut]) is model
            k = targets.shape[1]
            assert model.predict(X.iloc[cut:]).shape == (len(X) - cut, k)
            assert model.predict(X.iloc[10:60]).shape == (50, k)
            assert np.isfinite(model.predict(X)).all()


def test_prediction_with_history_and_streaming_continue_the_observer(frames):
    """predict(test, history=train) equals predicting everything and keeping the test rows; a streamer started
    on the training rows gives the same, one row at a time; an observer uses the measured temperatures."""
    X, y, cut = frames
    for cls in (LPTN, LPTNHybrid):
        model = cls(**CHEAP).fit(X.iloc[:cut], y.iloc[:cut])
        assert cls.history_length is None
        whole = model.predict(X)
        assert np.allclose(model.predict(X.iloc[cut:], history=X.iloc[:cut]), whole[cut:], atol=1e-9)
        streamer = model.streamer(X.iloc[:cut])
        rows = X.iloc[cut:cut + 200]
        streamed = np.array([streamer.update(rows.iloc[i]) for i in range(len(rows))])
        assert np.abs(streamed - whole[cut:cut + 200]).max() < 1e-4
    warmer = X.iloc[cut:].assign(T_spindle=X["T_spindle"].iloc[cut:] + 1.0)
    assert not np.allclose(model.predict(warmer, history=X.iloc[:cut]), whole[cut:], atol=1e-3), \
        "the measured temperatures must move the prediction"


def test_the_room_swing_is_taken_from_the_measured_column_and_the_hybrid_keeps_it(frames):
    """The room swing is not in the auto network (no ambient channel) but T_column measures it: the expansion map
    of the observed states (ridge chosen by blocked CV) takes it, and the hybrid's residual model keeps it."""
    X, y, cut = frames
    target = y[["disp_z"]]
    truth = target.iloc[cut:].to_numpy()[:, 0]
    rmse = {}
    for cls in (LPTN, LPTNHybrid):
        model = cls(**CHEAP).fit(X.iloc[:cut], target.iloc[:cut])
        rmse[cls.__name__] = float(np.sqrt(np.mean((model.predict(X.iloc[cut:])[:, 0] - truth) ** 2)))
    assert rmse["LPTN"] < 0.2, rmse  # the drift noise is 0.05 µm; the room alone moves disp_z by tens of µm
    assert rmse["LPTNHybrid"] <= 1.05 * rmse["LPTN"], rmse


def test_the_state_observer_starts_again_after_reset(frames):
    X, _, _ = frames
    obs = StateObserver(physics.network_from_dict(SPEC), ["T_spindle", "T_column"])
    t, speed = np.asarray(X.index, dtype=float), X["spindle_rpm"].to_numpy()
    ambient, temps = np.full(len(X), 22.0), X[["T_spindle", "T_column"]].to_numpy()
    first = obs.run(t[:100], speed[:100], ambient[:100], ambient[:100], temps[:100])
    obs.run(t[100:200], speed[100:200], ambient[100:200], ambient[100:200], temps[100:200])
    obs.reset()
    assert obs.x is None
    assert np.array_equal(obs.run(t[:100], speed[:100], ambient[:100], ambient[:100], temps[:100]), first)
    obs.reset()
    assert np.array_equal(obs.update(t[0], speed[0], 22.0, 22.0, temps[0]), first[0])


def test_pickle_round_trip(frames):
    X, y, cut = frames
    model = LPTNHybrid(**CHEAP).fit(X.iloc[:cut], y.iloc[:cut])
    again = pickle.loads(pickle.dumps(model))
    assert np.array_equal(model.predict(X.iloc[cut:]), again.predict(X.iloc[cut:]))


def test_input_roles_come_from_the_roles_the_study_passes_not_from_names():
    t = pd.Index(np.arange(5) * 60.0, name="time_s")
    X = pd.DataFrame({"T_spindle": 20.0 + np.arange(5), "rpm": [0, 0, 3000, 3000, 0], "ambient_C": 21.0}, index=t)
    with pytest.raises(ValueError, match="role 'speed'"):
        input_roles(X)  # no roles: a column named like a speed is not taken for one
    assert input_roles(X, speed_column="rpm") == ("rpm", None, ["T_spindle", "ambient_C"])
    X.attrs["roles"] = {"T_spindle": "speed", "rpm": "temperature", "ambient_C": "temperature"}
    assert input_roles(X) == ("T_spindle", None, ["rpm", "ambient_C"])  # roles, whatever the names say
    X.attrs["roles"] = {"T_spindle": "temperature", "rpm": "speed", "ambient_C": "ambient"}
    assert input_roles(X) == ("rpm", "ambient_C", ["T_spindle"])
    assert input_roles(X, speed_column="rpm", ambient_column=None) == ("rpm", "ambient_C", ["T_spindle"])
    with pytest.raises(ValueError, match="speed_column='n'"):
        input_roles(X, speed_column="n")


def test_registered_with_configs_and_search_spaces():
    names = registry.names("model")
    assert {"lptn", "lptn_hybrid"} <= set(names)
    for name, cls in (("lptn", LPTN), ("lptn_hybrid", LPTNHybrid)):
        assert cls.extra_input_roles == ("temperature", "speed", "ambient")
        conf = configs.node(registry.get("model", name))  # the config `thermodrift run model=<name>` composes
        assert conf["name"] == name
        model = registry.create("model", name, **conf["params"])
        assert isinstance(model, cls)
        assert set(conf["search_space"]) == set(cls.search_space()) <= set(model.get_params())
        for params in cls.get_test_params():
            assert set(params) <= set(model.get_params())
