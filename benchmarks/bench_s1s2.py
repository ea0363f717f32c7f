"""S1 and S2 selectors and compensation on the simulated machines: classes vs the machine's node groups, and
origin-translation compensation on S1's three ambient conditions.

* fuzzy_sensitivity on turning_centre_s1's 20 °C session (S1's 8 h run): its classes beside each sensor's
  dominant node group (adjusted Rand index; S1 reported 2 classes);
* gra_hierarchical on vmc_spindle_s2's first warm-up: the grades, groups and chosen points;
* compensation: for each ambient session, train ``--model`` (untuned defaults) on the other sessions and
  compensate the held-out one (S1: improvement 86/88/86 %).

    python benchmarks/bench_s1s2.py [--model transfer_function] [--out-cnc cnc_table.csv]
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd
from sklearn.metrics import adjusted_rand_score

from thermodrift.core import registry
from thermodrift.core.compensation import cnc_table, s1_ambient_evaluation, write_cnc_table
from thermodrift.core.physics.spec import load_network
from thermodrift.core.report import markdown


def node_groups(machine: str) -> dict[str, str]:
    """Each temperature sensor's dominant node group (ambient for a sensor mostly on the room)."""
    net = load_network(machine)
    group = {n.name: n.group for n in net.nodes}
    out = {}
    for s in net.sensors:
        if hasattr(s, "weights"):
            node = max(s.weights, key=s.weights.get)
            out[s.name] = group.get(node, node)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="transfer_function")
    parser.add_argument("--out-cnc", default=None, help="write the CNC table of the 20 °C session here (CSV)")
    args = parser.parse_args()

    rec = registry.create("dataset", "turning_centre_s1")
    session = rec.select(np.flatnonzero(rec.conditions().to_numpy() == "ambient_20C")[:420])
    fuzzy = registry.create("selector", "fuzzy_sensitivity").fit(session.temperatures, session.displacements)
    truth = node_groups("turning_centre_s1")
    classes = fuzzy.report_["fuzzy_classes"].assign(node_group=lambda t: t["sensor"].map(truth))
    ari = adjusted_rand_score(classes["node_group"], classes["class"])
    print(f"## fuzzy_sensitivity on turning_centre_s1 (20 °C session, {len(session)} samples)\n")
    print(f"lambda {fuzzy.lambda_:.4f}, {classes['class'].nunique()} classes, selected {', '.join(fuzzy.selected_)}; "
          f"adjusted Rand index vs node groups {ari:.2f}\n")
    print(markdown(classes))

    rec2 = registry.create("dataset", "vmc_spindle_s2")
    first = rec2.select(np.flatnonzero(rec2.conditions().to_numpy() == rec2.conditions().iloc[0]))
    gra = registry.create("selector", "gra_hierarchical").fit(first.temperatures, first.displacements)
    groups = gra.report_["gra_groups"].assign(node_group=lambda t: t["sensor"].map(node_groups("vmc_spindle_s2")))
    print(f"## gra_hierarchical on vmc_spindle_s2 (first warm-up): selected {', '.join(gra.selected_)}\n")
    print(markdown(groups))
    print(markdown(gra.report_["gra_selection_path"]))

    table, results = s1_ambient_evaluation(model=args.model)
    print(f"## Origin-translation compensation, {args.model} trained on the other sessions\n")
    print(markdown(table, digits=1))
    if args.out_cnc:
        fold = results["ambient_20C"]
        key_sensor = fold.selected[0]
        key = rec.data[key_sensor].iloc[np.searchsorted(rec.time_s, fold.time_s)]
        key.index = fold.time_s
        path = write_cnc_table(cnc_table(fold.predictions["model"], [0.0, 150.0], 0.0, key, axis="x"), args.out_cnc)
        print(f"CNC table (radial error at Z = 0 and 150 mm, key temperature {key_sensor}): {path}")


if __name__ == "__main__":
    pd.set_option("display.width", 200)
    main()
