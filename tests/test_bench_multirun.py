"""The multi-run benchmark's recordings (benchmarks/bench_multirun.py): each day one run through the public file
format, each a cold start at its own hall temperature, and the tasks hold out the day they name."""

from pathlib import Path

import numpy as np

from thermodrift.core import registry, splits
from thermodrift.core.automl import folds as inner

from support import load_file

BENCH = Path(__file__).resolve().parent.parent / "benchmarks" / "bench_multirun.py"


def test_each_day_is_a_cold_start_read_back_as_its_own_run(tmp_path):
    bench = load_file(BENCH)
    spec, info = bench.task_spec("lumped", 1, "hot", 3, tmp_path)
    hall = info["hall_degC"]
    assert info["day"] == max(list(hall)[:-1], key=hall.get) != list(hall)[-1]
    rec = registry.create("dataset", spec.dataset, **spec.dataset_params)
    runs = rec.runs().to_numpy()
    assert list(dict.fromkeys(runs)) == list(hall)
    temps = [c for c in rec.columns("temperature")]
    for day in hall:
        rows = rec.data[runs == day]
        first = rows[temps].iloc[0].to_numpy()
        # at rest with the morning's hall: every sensor within its offsets of the ambient reading, then warmer
        assert np.all(np.abs(first - rows["ambient_degC"].iloc[0]) < 2.0)
        assert rows["T_front_bearing"].max() > first.max() + 2.0
    assert np.ptp([rec.data.loc[runs == d, "ambient_degC"].iloc[0] for d in hall]) > 1.0  # a hall level per day
    (fold,) = splits.make_split(spec.split, **spec.split_params).folds(rec)
    assert set(runs[fold.test]) == {info["day"]} and set(runs[fold.train]) == set(hall) - {info["day"]}
    assert len(inner.inner_folds(rec, fold.train)) == 2  # one inner fold per other training day


def test_a_task_without_speed_reads_back_without_a_speed_channel_and_leaves_out_what_needs_one(tmp_path):
    from thermodrift.core.automl import space

    bench = load_file(BENCH)
    spec, _ = bench.task_spec("fd", 0, "last", 2, tmp_path, speed=False)
    rec = registry.create("dataset", spec.dataset, **spec.dataset_params)
    roles = {ch.role for ch in rec.channels.values()}
    assert "speed" not in roles and "spindle_rpm" not in rec.channels
    can = {f.name for f in space.families(roles=roles)}
    assert "mlr" in can and "lptn" not in can and "lptn_hybrid" not in can
