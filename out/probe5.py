exec(open('out/probe4.py').read().split("e = F.fit(m_true")[0])
from thermodrift.core import registry
from thermodrift.core.physics.stochastic.selection import ti_start, extension_starts, DEFAULT_HTC
from thermodrift.core.physics.stochastic.building import htc
base = sto.load('building_ti'); d = B.series(base, df)
first = ti_start(base, d); origin = first.values()
ti = F.fit(first, d, seed=seed, starts=2, information=False)
print('Ti', ti.loglik, {k: round(v,4) for k,v in ti.values.items()})
b = ti.model.with_values(ti.values); scale = htc(ti.model, ti.values)/DEFAULT_HTC
for mid in ['building_th','building_ts']:
    ext, also = extension_starts(ti, type(registry.create('mechanism', mid))().apply(b), scale, origin)
    for v in [ext.values()] + also:
        print(mid, round(F.loglik(ext, d, {**ext.values(), **v}),1), {k: round(x,4) for k,x in v.items()})
