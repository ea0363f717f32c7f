import sys, time
sys.path.insert(0,'.')
from benchmarks import bench_greybox as B
from benchmarks.independent import house_sde
cases = [int(a) for a in sys.argv[1].split(',')]
sims = sys.argv[2].split(',') if len(sys.argv) > 2 else ['independent','engine']
cl = list(house_sde.case_list(False, max(cases)+1))
for c in cases:
    seed, structure = cl[c]
    house, df = house_sde.make_case(seed, structure)
    for sim in sims:
        rec = df if sim == 'independent' else B.engine_recording(house, df, seed)
        t = time.perf_counter()
        row = B.score_case(house, rec, seed)
        print(sim, seed, structure, '->', row['selected'], ' > '.join(row['path']), f"htc {100*row['htc_rel_err']:.1f}%", row['covered'], round(time.perf_counter()-t), 's', flush=True)
