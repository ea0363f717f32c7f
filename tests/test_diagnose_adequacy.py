"""The baseline's expansion map chosen on held-out data: a lag the drift reads its nodes through is kept, none is
added where the drift reads them directly, and a lagged reading does not disturb the node it reads."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from thermodrift.core import physics
from thermodrift.core.physics.calibration import predict
from thermodrift.core.physics.diagnose import adequacy, inner_split, screening
from thermodrift.core.physics.diagnose.concealed import concealed_case
from thermodrift.core.physics.network import TemperatureSensor
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.recording import Recording


@pytest.fixture(scope="module")
def null_case():
    return concealed_case(physics.load_network("demo_spindle"), None, 4, hours=14.0, dt_s=120.0)


def _split(rec):
    fit, inner = inner_split(rec)
    return np.flatnonzero(inner), np.flatnonzero(fit & ~inner)


def _cal(net):
    return SimpleNamespace(network=net, sigma={s.name: (s.noise_K if isinstance(s, TemperatureSensor) else s.noise_um)
                                               for s in net.sensors},
                           channel_kind={s.name: ("temperature" if isinstance(s, TemperatureSensor)
                                                  else "displacement") for s in net.sensors})


def test_a_lagged_reading_follows_its_node_without_disturbing_it(null_case):
    net, sc = null_case.baseline, Scenario.from_recording(null_case.recording)
    lagged = adequacy.with_lags(net, (0.25,))
    added = [n for n in lagged.node_names if adequacy.is_lag_node(lagged, n)]
    assert added and all(set(added) <= set(o.sensitivity_um_K) for o in lagged.outputs)
    (plain, X0), (with_lag, X1) = predict(net, sc), predict(lagged, sc)
    temps = [s.name for s in net.sensors if isinstance(s, TemperatureSensor)]
    assert np.abs(plain[temps].to_numpy() - with_lag[temps].to_numpy()).max() < 0.01  # below a sensor step
    lag = added[0]
    source = next(e.a for e in lagged.edges if e.b == lag)
    x, y = X1[:, lagged.node_names.index(source)], X1[:, lagged.node_names.index(lag)]
    assert np.abs(y - x).max() > 0.05                               # it lags a warming node ...
    dt = np.diff(sc.time_s)
    ref = np.empty_like(x)
    ref[0] = y[0]
    for k in range(1, len(x)):                                      # ... as a first-order lag of 0.25 h does
        a = np.exp(-dt[k - 1] / 900.0)
        ref[k] = a * ref[k - 1] + (1 - a) * x[k - 1]
    assert np.abs(y - ref).max() < 0.1 * np.abs(y - x).max()


def test_the_lag_the_drift_reads_through_is_kept_and_none_is_added_otherwise(null_case):
    rec, net = null_case.recording, null_case.baseline
    sc = Scenario.from_recording(rec)
    inner, val = _split(rec)
    chosen, table = adequacy.choose_lags(_cal(net), rec, inner, val, sc, screening.baseline_of)
    assert chosen == () and [r["chosen"] for r in table] == [True, False, False]
    # the same machine whose drift reads its hottest node through a 0.25 h lag as well
    lagged = adequacy.with_lags(net, (0.25,))
    lag = next(n for n in lagged.node_names if adequacy.is_lag_node(lagged, n))
    outputs = [dataclasses.replace(o, sensitivity_um_K={**o.sensitivity_um_K, lag: 4.0}) for o in lagged.outputs]
    truth = predict(lagged.replace(*outputs), sc)[0]
    data = rec.data.copy()
    for c in rec.columns("displacement"):
        data[c] += truth[c].to_numpy() - predict(net, sc)[0][c].to_numpy()
    chosen, table = adequacy.choose_lags(_cal(net), Recording(data, rec.channels), inner, val, sc,
                                         screening.baseline_of)
    assert chosen == (0.25,)
    kept = next(r for r in table if r["chosen"])
    assert kept["heldout_drift_error"] < 0.5 * table[0]["heldout_drift_error"]


def test_lagged_readings_are_marked_by_their_group_not_their_name(null_case):
    from thermodrift.core import registry
    from thermodrift.core.physics.network import Edge, Node

    net = null_case.baseline
    lagged = adequacy.with_lags(net, (0.1,))
    added = set(lagged.node_names) - set(net.node_names)
    assert added and all(lagged.node(n).group == adequacy.LAG_GROUP for n in added)
    for mid in registry.names("mechanism"):                     # no mechanism finds a part to act on there
        for options in registry.get("mechanism", mid).factory.places(lagged):
            assert not screening._names_lag_node(lagged, options), (mid, options)
    # a real part whose name happens to carry the prefix is a place like any other
    housing = net.nodes_in("housing")[0]
    real = net.add(Node("lag_cover", 2.0e4, "housing"), Edge("lag_cover-edge", housing, "lag_cover", 5.0))
    assert not adequacy.is_lag_node(real, "lag_cover")
    assert any("lag_cover" in (o.get("nodes") or []) for mid in registry.names("mechanism")
               for o in registry.get("mechanism", mid).factory.places(real))
