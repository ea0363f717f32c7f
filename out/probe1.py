import sys, time, numpy as np
sys.path.insert(0,'.')
from benchmarks import bench_greybox as B
from benchmarks.independent import house_sde
from thermodrift.core.physics import stochastic as sto
import importlib; F = importlib.import_module("thermodrift.core.physics.stochastic.fit")
from scipy.optimize import minimize
seed, structure = list(house_sde.case_list(False, 2))[1]
house, df = house_sde.make_case(seed, structure)
rec = B.engine_recording(house, df, seed)
net = B.network(structure)
data = B.series(net, rec)
tv = B.truth(house)
m_true = net.with_values({p.name: tv[p.name] for p in net.params})
print(structure, len(data), {p.name: round(tv[p.name],4) for p in net.params})
t=time.perf_counter(); ll=F.loglik(m_true, data, m_true.values()); print('ll at truth', ll, time.perf_counter()-t)
t=time.perf_counter(); e=F.fit(m_true, data, starts=1, information=False); print('fit from truth', e.loglik, e.n_evals, time.perf_counter()-t)
# selection start
base = sto.load('building_ti')
from thermodrift.core.physics.stochastic.selection import ti_start
ti = F.fit(ti_start(base, data), data, starts=2, information=False)
print('Ti', ti.loglik, ti.n_evals, ti.seconds, ti.starts)
from thermodrift.core import registry
from thermodrift.core.physics.stochastic.building import rescaled, htc
from thermodrift.core.physics.stochastic.selection import DEFAULT_HTC
base = ti.model.with_values(ti.values)
scale = htc(ti.model, ti.values)/DEFAULT_HTC
for mid in ['building_tm','building_te','building_th','building_ts']:
    m = registry.create('mechanism', mid)
    ext = type(m)().apply(base)
    new = {p.name for p in ext.params} - {p.name for p in base.params}
    start = rescaled(ext, scale)
    vals = {k: v for k, v in start.values().items() if k in new}
    job = ext.with_values(vals)
    params = job.parameters
    eta0 = np.array([p.to_eta(p.value) for p in params])
    scale_n = 1/len(data)
    def obj(eta):
        ll = F.loglik(job, data, F._values(params, eta))
        return -ll*scale_n if np.isfinite(ll) else 1e10
    t=time.perf_counter()
    with F.one_thread():
        r = minimize(obj, eta0, method='L-BFGS-B', bounds=[(-25,25)]*len(params), options={'maxiter':300,'ftol':1e-8})
    print(mid, 'start', -obj(eta0)/scale_n, '->', -r.fun/scale_n, r.nit, r.nfev, r.message, round(time.perf_counter()-t,1))
    print('   ', {p.name: round(v,4) for p, v in zip(params, [p.from_eta(e) for p,e in zip(params,r.x)])})
