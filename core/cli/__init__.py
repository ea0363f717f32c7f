"""The ``thermodrift`` command line: one verb per module, imported only when used.

Each verb module exposes ``configure(parser)`` and ``run(args) -> int``. Bad input (:class:`InputError`) is
reported as one line on stderr with exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
import warnings

from thermodrift.core.errors import InputError, PluginError

# verb -> (module, one-line help). `run` is the Hydra app and parses its own overrides.
VERBS = {
    "plugins": ("thermodrift.core.cli.plugins", "List every registered component by kind with its origin."),
    "validate": ("thermodrift.core.cli.validate", "Check a recording (table + manifest) and print a summary."),
    "run": ("thermodrift.core.cli.run", "Run experiments (Hydra overrides; -m for a grid)."),
    "automl": ("thermodrift.core.cli.automl", "Search selector x features x model family x settings (run's overrides)."),
    "simulate": ("thermodrift.core.cli.simulate", "Write a simulated recording (table + manifest + truth)."),
    "calibrate": ("thermodrift.core.cli.calibrate", "Calibrate a thermal network to a recording."),
    "diagnose": ("thermodrift.core.cli.diagnose", "Find the physics a thermal network leaves out of a recording."),
    "bench": ("thermodrift.core.cli.bench", "Run the benchmarks (samplers, physics)."),
    "report": ("thermodrift.core.cli.report", "The published studies' tables (S1 Table 7, S2) from a sweep in MLflow."),
    "export": ("thermodrift.core.cli.export", "Write a logged run's model as a data-only compensator package."),
    "compensate": ("thermodrift.core.cli.compensate", "Stream a recording through a package into CNC values."),
}


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``thermodrift`` console script."""
    os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
    warnings.showwarning = _warning_line
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "run" and ("-h" in argv[1:] or "--help" in argv[1:]):
        from thermodrift.core.cli import run_options  # no Hydra, MLflow or torch: answers fast
        print(run_options.help_text())
        return 0
    verb = argv[0] if argv else ""
    if argv and argv[0] == "automl":  # `thermodrift run automl=default ...`: the same overrides and checks
        if "-h" in argv[1:] or "--help" in argv[1:]:
            from thermodrift.core.cli import automl as automl_help
            print(automl_help.help_text())
            return 0
        from thermodrift.core.cli import run_options
        argv = ["run", *run_options.automl_overrides(argv[1:])]
    if argv and argv[0] == "run":  # Hydra owns the rest of the command line
        from thermodrift.core import registry, tracking_faults
        from thermodrift.core.cli import run_options

        def run_app() -> int:
            # Before the slow imports (plugins, Hydra, MLflow, torch): a misspelt group option or key is answered
            # from the saved listing of installed components, as fast as --help, and a dead server is reported.
            run_options.check_flags(argv[1:], verb)
            run_options.check_overrides(run_options.split_flags(argv[1:])[1], registry.listing())
            tracking_faults.precheck(argv[1:])
            from thermodrift.core.cli import run as app
            return app.main(argv[1:])
        return _guard(run_app)
    parser = argparse.ArgumentParser(prog="thermodrift", description=plain(__doc__.splitlines()[0]))
    sub = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    for verb, (module_name, help_text) in VERBS.items():
        if verb in ("run", "automl"):
            sub.add_parser(verb, help=help_text, add_help=False)
            continue
        vparser = sub.add_parser(verb, help=help_text, description=help_text)
        vparser.set_defaults(_module=module_name)
    # Only the chosen verb's module is imported, so `thermodrift --help` stays fast.
    if not argv or argv[0] not in VERBS:
        parser.parse_args(argv)
        return 2
    module = importlib.import_module(VERBS[argv[0]][0])
    module.configure(sub.choices[argv[0]])
    args = parser.parse_args(argv)
    if getattr(args, "no_progress", True) is False and not sys.stderr.isatty():
        args.no_progress = True  # a bar redrawn in a file or a pipe becomes one long line
    return _guard(lambda: module.run(args))


BROKEN_PIPE = 141  # 128 + SIGPIPE: the status of a tool whose reader went away (`yes | head -1`)


def _guard(fn) -> int:
    try:
        code = int(fn() or 0)
        sys.stdout.flush()  # here, not at exit: a reader that has gone away is answered below
        return code
    except BrokenPipeError:  # `thermodrift plugins | head -1`: the reader has all it wanted, nothing to report
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so Python's flush at exit stays quiet
        return BROKEN_PIPE
    except (InputError, PluginError) as exc:
        error_line(f"thermodrift: error: {exc}")
        return 2
    except KeyboardInterrupt:
        print("thermodrift: interrupted; completed trials are kept in the Optuna storage", file=sys.stderr)
        return 130


# reStructuredText markup of docstrings, in the order it is undone: a role with an explicit title
# (:func:`title <target>`), a role whose target starts with ~ (the last dotted part is shown), any other role,
# a literal (``x``), interpreted text or a link (`x`, `x`_), strong emphasis (**x**).
_RST = [(re.compile(r":[\w:+-]+:`([^`<]*?)\s*<[^`>]*>`"), r"\1"),
        (re.compile(r":[\w:+-]+:`~(?:[^`]*\.)?([^`.]+)`"), r"\1"),
        (re.compile(r":[\w:+-]+:`([^`]+)`"), r"\1"),
        (re.compile(r"``(.+?)``"), r"\1"),
        (re.compile(r"`([^`]+)`_{0,2}"), r"\1"),
        (re.compile(r"\*\*(\S(?:.*?\S)?)\*\*"), r"\1")]


def plain(text: str) -> str:
    """``text`` (a docstring line or a config comment) with its reStructuredText markup rendered as plain text,
    for help output: ``:class:`~thermodrift.core.registry.Registry``` -> ``Registry``, ````x```` -> ``x``."""
    for pattern, repl in _RST:
        text = pattern.sub(repl, text)
    return text


_WARNED: set[str] = set()


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as one line on stderr, once per text (Python's own format adds the source file and line, and
    repeats a text raised from two places)."""
    text = " ".join(str(message).split())
    if text not in _WARNED:
        _WARNED.add(text)
        error_line(f"thermodrift: warning: {text}")


def error_line(text: str) -> None:
    """``text`` on stderr on a line of its own, also while a progress bar is still drawn there."""
    if "tqdm" in sys.modules:
        from tqdm import tqdm

        tqdm.write(text, file=sys.stderr)
    else:
        print(text, file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
