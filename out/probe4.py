import sys, time, importlib, numpy as np
sys.path.insert(0,'.')
from benchmarks import bench_greybox as B
from benchmarks.independent import house_sde
from thermodrift.core.physics import stochastic as sto
F = importlib.import_module("thermodrift.core.physics.stochastic.fit")
from thermodrift.core.physics.stochastic.selection import forward_select
c = int(sys.argv[1])
seed, structure = list(house_sde.case_list(False, c+1))[c]
house, df = house_sde.make_case(seed, structure)
net = B.network(structure); data = B.series(net, df); tv = B.truth(house)
m_true = net.with_values({p.name: tv[p.name] for p in net.params})
print(structure, {k: round(v,4) for k,v in m_true.values().items()})
e = F.fit(m_true, data, starts=1, information=False); print('fit from truth', round(e.loglik,1), {k: round(v,4) for k,v in e.values.items()})
base = sto.load('building_ti')
sel = forward_select(base, B.series(base, df), seed=seed, progress=print)
