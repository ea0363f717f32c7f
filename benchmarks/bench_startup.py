"""Start-up cost: how long a fresh process takes to load the plugins, next to the imports it avoids.

Each command runs ``--repeats`` times in a new Python process (wall seconds, median and minimum); the rows
share one run, so the ratios hold on a busy machine too. ``registry.default()`` loads every installed plugin
(selectors, models, optimizers, datasets, mechanisms); ``thermodrift plugins`` adds the listing itself;
``thermodrift run --help`` adds the shipped YAML files and ``conf/config.yaml`` (its target: under 3 s on an
idle machine, without importing Hydra, MLflow or torch); it reads the component names from the listing that
the last full load saved (``registry.listing()``), and the row "no saved listing" shows it without
(``THERMODRIFT_NO_CACHE=1``: the first call after installing or changing a plugin). A misspelt group option or
key (``run model=mrl``, ``run n_trial=5``) is answered from the same listing before any plugin is imported, so
its rows match the ``--help`` row. The last column names the heavy modules the process ended up importing; the
first line the machine's load average, since a busy machine stretches every row.

    python benchmarks/bench_startup.py            # or: thermodrift bench startup
    python benchmarks/bench_startup.py --repeats 10
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time

HEAVY = ("torch", "scipy.signal", "scipy.stats", "sklearn", "pandas", "mlflow", "hydra")
PROBE = "; import sys; print('heavy:', ' '.join(m for m in {heavy!r} if m in sys.modules))"
COMMANDS = {
    "python -c pass": "pass",
    "import thermodrift.core": "import thermodrift.core",
    "registry.default()": "from thermodrift.core import registry; registry.default()",
    "thermodrift plugins": "from thermodrift.core.cli import main; main(['plugins'])",
    "thermodrift run --help": "from thermodrift.core.cli import main; main(['run', '--help'])",
    "thermodrift run model=mrl (misspelt option)": "from thermodrift.core.cli import main; main(['run', 'model=mrl'])",
    "thermodrift run n_trial=5 (misspelt key)": "from thermodrift.core.cli import main; main(['run', 'n_trial=5'])",
    "thermodrift run --help, no saved listing": "import os; os.environ['THERMODRIFT_NO_CACHE'] = '1'; "
                                                "from thermodrift.core.cli import main; main(['run', '--help'])",
    "import torch": "import torch",
    "import scipy.signal": "import scipy.signal",
}


def timed(code: str) -> tuple[float, float, str]:
    """Wall and CPU (user + system) seconds of one fresh interpreter running ``code``, and the heavy modules it
    imported. On a busy machine the wall time stretches; the CPU time is what the process itself needed."""
    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code + PROBE.format(heavy=HEAVY)], capture_output=True,
                         text=True, check=True, env=env).stdout
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    heavy = next(line for line in reversed(out.splitlines()) if line.startswith("heavy:"))
    return wall, cpu, heavy.removeprefix("heavy:").strip()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    timed("pass")  # warm the file cache once
    rows = {name: [timed(code) for _ in range(args.repeats)] for name, code in COMMANDS.items()}
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"fresh-process wall seconds, {args.repeats} repeats (Python {sys.version.split()[0]}, "
          f"{os.cpu_count()} CPUs, load average {load})")
    print("| command | median wall s | min wall s | median CPU s | heavy modules imported |\n|---|---|---|---|---|")
    for name, runs in rows.items():
        wall, cpu = [r[0] for r in runs], [r[1] for r in runs]
        print(f"| {name} | {statistics.median(wall):.2f} | {min(wall):.2f} | {statistics.median(cpu):.2f} "
              f"| {runs[-1][2] or '-'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
