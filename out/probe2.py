exec(open('out/probe1.py').read().split("# selection start")[0])
base = sto.load('building_ti')
from thermodrift.core.physics.stochastic.selection import ti_start
st = ti_start(base, data)
print('ti_start', st.values())
for aw in [None, 0.5, 2.0, 5.0]:
    m = st if aw is None else st.with_values({'Aw': aw})
    e = F.fit(m, data, starts=1, information=False)
    print(aw, round(e.loglik,1), {k: round(v,4) for k,v in e.values.items()}, e.n_evals)
tm = B.network('TiTm')
tm_d = tm.with_values({'Ci':1.0,'Ria':10,'Aw':2,'Cm':4,'Rim':2})
e = F.fit(tm_d, data, starts=1, information=False); print('TiTm from crude', round(e.loglik,1), {k: round(v,4) for k,v in e.values.items()})
