"""Probe: on which concealed-effect recordings can ``diagnose`` test the planted mechanism at all?

``diagnose`` screens a mechanism only at places where it adds something its baseline cannot already fit
(:func:`~thermodrift.core.physics.diagnose.screening.candidates`): a mechanism whose driver is missing or constant,
that has no place in the network, or that is nested in the baseline at every place (an extra conductance to the
ambient parallel to the free one every ``auto`` node has; a tilt between nodes the expansion map already reads) is
rejected with its reason before any fit. On such a recording no rule can name it, so the share of hidden cases
whose planted mechanism is testable bounds the finder's top-1 from above. This probe runs that screen for the
planted mechanism alone against the ``auto`` baseline of each recording (its structure, not its calibration) and
prints, per mechanism, the cases where it is testable, nested or skipped::

    python benchmarks/probe_testable.py                        # both independent generators, development half
    python benchmarks/probe_testable.py --generator fd --per-mechanism 1
    python benchmarks/probe_testable.py --only ambient_coupling thermal_tilt --per-mechanism 40

The ``auto`` baseline here has the default hidden nodes; the hidden nodes and lagged readings the adequacy step may
add change nothing in the count (each hidden node has its own free conductance to the ambient and is read by every
drift channel; a lagged reading is no place for a mechanism).
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
from pathlib import Path

import numpy as np

from thermodrift.core import registry as registry_module
from thermodrift.core.physics.calibration import auto_network
from thermodrift.core.physics.diagnose import screening
from thermodrift.core.physics.network import TemperatureSensor
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.recording import load_recording

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import independent  # noqa: E402 - the independent generators next to this script


def verdict(recording, mechanism: str, registry=None) -> tuple[str, str]:
    """("testable", "k places"), ("nested", reason) or ("skipped", reason): the screen's decision for
    ``mechanism`` against the ``auto`` baseline of ``recording``."""
    registry = registry or registry_module.default()
    auto = auto_network(recording)
    net, free = auto.network, frozenset(p for fp in auto.free for p in fp.paths)
    channels = [s.name for s in net.sensors]
    sigma = np.maximum([s.noise_K if isinstance(s, TemperatureSensor) else s.noise_um for s in net.sensors], 0.01)
    scenario = Scenario.from_recording(recording)
    measured = recording.data[channels].to_numpy(dtype=float)
    base = screening.baseline_of(net, scenario, channels, measured, np.arange(len(recording)), sigma)
    found, rejected = screening.candidates(registry, base, scenario, channels, recording, [mechanism], free)
    if found:
        return "testable", f"{len(found)} places"
    reason = rejected[0]["reason"]
    return ("nested" if reason.startswith("nested") else "skipped"), reason


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--generator", nargs="+", choices=independent.GENERATORS, default=list(independent.GENERATORS))
    ap.add_argument("--per-mechanism", type=int, default=3, help="hidden cases per mechanism (3: the full set)")
    ap.add_argument("--sealed-base", type=int, metavar="SEED",
                    help="a sealed range instead of the development half (the recordings' sensors and drivers only "
                         "are read, no diagnosis runs)")
    ap.add_argument("--only", nargs="+", metavar="MECHANISM", help="only the hidden cases of these mechanisms")
    args = ap.parse_args(argv)
    cases = [(s, h) for s, h, _ in independent.case_list(args.sealed_base is not None, args.per_mechanism, 0,
                                                         args.sealed_base) if h and (not args.only or h in args.only)]
    print("| generator | mechanism | cases | testable | nested | skipped | a reason |")
    print("|---|---|---:|---:|---:|---:|---|")
    for generator in args.generator:
        counts: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
        reasons: dict[str, str] = {}
        for seed, hidden in cases:
            gen = independent.make_case(seed, hidden, generator=generator)
            with tempfile.TemporaryDirectory() as folder:
                recording = load_recording(*gen.write(Path(folder)))
            kind, why = verdict(recording, hidden)
            counts[hidden][kind] += 1
            if kind != "testable":
                reasons.setdefault(hidden, why)
        total = collections.Counter()
        for mechanism, c in counts.items():
            total.update(c)
            why = reasons.get(mechanism, "").split(", so ")[0].split("; ")[0]
            print(f"| {generator} | {mechanism} | {sum(c.values())} | {c['testable']} | {c['nested']} | "
                  f"{c['skipped']} | {why} |")
        n = sum(total.values())
        print(f"| {generator} | **all** | {n} | {total['testable']} ({total['testable'] / n:.0%}: the top-1 "
              f"ceiling) | {total['nested']} | {total['skipped']} | |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
