"""Options that several verbs share, each defined once: ``--out`` (where a verb writes) and ``--tracking-uri``
(the MLflow store, one default for every verb: :data:`~thermodrift.core.tracking_faults.DEFAULT_URI`).

Light on purpose (no MLflow import), so a verb's ``--help`` stays fast.
"""

from __future__ import annotations

import argparse

from thermodrift.core.tracking_faults import DEFAULT_URI


def add_out(parser: argparse.ArgumentParser, what: str, default: str | None = None) -> None:
    """``--out PATH``: ``what`` the verb writes there; required when ``default`` is None."""
    parser.add_argument("--out", metavar="PATH", default=default, required=default is None,
                        help=what if default is None else f"{what} (default: {default})")


def add_tracking_uri(parser: argparse.ArgumentParser, optional: bool = False) -> None:
    """``--tracking-uri URI``: the MLflow store read or written (default :data:`DEFAULT_URI`). With ``optional``
    the verb logs only when asked: the option alone logs to the default store, without it nothing is logged."""
    if optional:
        parser.add_argument("--tracking-uri", metavar="URI", nargs="?", const=DEFAULT_URI, default=None,
                            help=f"log the run to MLflow at URI (the option alone: {DEFAULT_URI}; "
                                 "default: not logged)")
    else:
        parser.add_argument("--tracking-uri", metavar="URI", default=DEFAULT_URI,
                            help=f"MLflow tracking URI (default: {DEFAULT_URI})")
