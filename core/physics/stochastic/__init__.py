"""Stochastic grey-box identification: linear RC networks as SDEs, the continuous–discrete Kalman filter's
likelihood, maximum likelihood with Hessian intervals, predictions, residual whiteness and forward selection.

Public API::

    from thermodrift.core.physics import stochastic as sto

    net = sto.load("building_ti")                    # conf/network/building_ti.yaml (an RCNetwork) or a path
    data = sto.Series.of(t_h, u, y)                  # times (h), inputs (rows × m, net.input_names order), outputs
    est = sto.fit(net, data, seed=0, starts=3)       # ML: est.values, est.loglik, est.n_params, est.intervals,
                                                     #     est.unidentifiable, est.table(), est.derived(fn)
    f = est.filtered()                               # one-step innovations f.e, variances f.S, f.standardized,
                                                     # predicted / filtered states, f.loglik
    yk = sto.k_step(est.system, data, f, k=96)       # k-step predictions (rows × outputs), NaN for the first k
    sto.whiteness.summary(f.standardized[:, 0])      # ACF and cumulated-periodogram whiteness
    sto.simulate(net.system(values), data, seed=1)   # a sample path of the SDE (outputs with noise)
    sel = sto.forward_select(net, data, seed=0)      # building forward selection from building_ti
    sto.structure_name(net), sto.htc(net, values)    # "TiTeTh", heat-transfer coefficient (heat unit / K)

    mech = registry.create("mechanism", "building_te")   # the building library: building_ti, _te, _th, _tm,
    net2 = mech.apply(net)                               # _ts, _aeria (plugins/mechanisms/building_*.py)

Any object with ``name``, ``parameters`` (tuple of :class:`Param`) and ``system(values) -> System`` can be fitted
(:class:`System`: A (levels × n × n, per time unit), B, C, D, process-noise σ per state, measurement r per output;
several levels for the machine networks, :mod:`.machine`).

Modules: :mod:`.sde` (System, Series, exact/Van Loan discretisation), :mod:`.kalman` (filter, likelihood,
k-step, simulation), :mod:`.fit` (Param, ML, Hessian), :mod:`.whiteness`, :mod:`.rc` (RCNetwork and its spec),
:mod:`.building` (the building library's base, names and HTC), :mod:`.selection` (forward selection).
"""

from thermodrift.core.physics.stochastic import whiteness
from thermodrift.core.physics.stochastic.building import htc, structure_name
from thermodrift.core.physics.stochastic.fit import Estimate, Param, fit
from thermodrift.core.physics.stochastic.kalman import Filtered, k_step, simulate
from thermodrift.core.physics.stochastic.kalman import run as filter_run
from thermodrift.core.physics.stochastic.rc import RCNetwork, load, network_from_dict
from thermodrift.core.physics.stochastic.sde import Series, System

__all__ = ["Estimate", "Filtered", "Param", "RCNetwork", "Series", "System", "filter_run", "fit", "htc", "k_step",
           "load", "network_from_dict", "simulate", "structure_name", "whiteness"]
