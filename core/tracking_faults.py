"""A tracking server that is down at the start or dies during a study costs no completed trial.

At the start, :func:`check` asks the server's ``/health`` with a short timeout and reports a dead server as
one line (exit 2). MLflow's own HTTP retries (7 with exponential back-off, minutes in all) are shortened so a
server that dies later is noticed in seconds. Trials live in the Optuna storage, not in MLflow, so
:class:`BufferedCallback` keeps the study going while the server is away: trial metrics wait in memory and are
flushed when the server answers again. If it is still away when the job logs its result, the job ends with one
line saying the study is intact and that re-running the same command logs it (the study resumes complete).
"""

from __future__ import annotations

import os
import urllib.error
import urllib.request

from thermodrift.core.errors import InputError

DEFAULT_URI = "sqlite:///mlflow.db"  # where runs land when no tracking URI is given (conf/config.yaml says the same)

CHECK_TIMEOUT_S = 3.0


def failures() -> tuple[type[BaseException], ...]:
    """What an MLflow client call raises when the server is unreachable or answers with an error page
    (imported on use: ``thermodrift run`` checks the server before it imports MLflow)."""
    import requests
    from mlflow.exceptions import MlflowException

    return MlflowException, requests.exceptions.RequestException, ConnectionError, TimeoutError


def precheck(overrides: list[str]) -> None:
    """Check a ``tracking.uri=http...`` given on the command line before the slow imports of a run."""
    uris = [o.split("=", 1)[1] for o in overrides if o.lstrip("+").startswith("tracking.uri=")]
    if uris:
        check(uris[-1])


def is_remote(uri: str | None) -> bool:
    return bool(uri) and uri.split("://", 1)[0] in ("http", "https")


def check(uri: str | None) -> None:
    """Raise a one-line :class:`InputError` unless the tracking server at ``uri`` answers within seconds;
    local stores (``sqlite:///...``, folders) need no check."""
    if not is_remote(uri):
        return
    os.environ.setdefault("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "1")
    os.environ.setdefault("MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR", "1")
    os.environ.setdefault("MLFLOW_HTTP_REQUEST_TIMEOUT", "10")
    try:
        with urllib.request.urlopen(uri.rstrip("/") + "/health", timeout=CHECK_TIMEOUT_S) as reply:
            if reply.status == 200:
                return
            problem = f"HTTP {reply.status}"
    except urllib.error.HTTPError as exc:
        problem = f"HTTP {exc.code}"
    except (urllib.error.URLError, OSError) as exc:
        problem = str(getattr(exc, "reason", exc))
    raise InputError(f"the MLflow tracking server at {uri} does not answer ({problem})",
                     hint=f"start it (mlflow server ...), or set tracking.uri={DEFAULT_URI}")


def lost(uri: str, study_name: str, storage: str | None, exc: BaseException) -> InputError:
    """The one-line error for a server that stopped answering after the study started."""
    where = f" in {storage}" if storage else ""
    first = " ".join(str(exc).split())[:200]
    return InputError(f"the MLflow tracking server at {uri} stopped answering ({first}); every completed trial "
                      f"is kept in study {study_name!r}{where}",
                      hint="run the same command again once the server is back: it resumes and logs the result")


class BufferedCallback:
    """Optuna callback around ``inner`` (e.g. the MLflow trial logger) that never stops the study when the
    tracking server is away: trials wait in ``pending`` and go out, in order, once a call succeeds again."""

    def __init__(self, inner):
        self.inner = inner
        self.pending: list = []

    def __call__(self, study, trial) -> None:
        self.pending.append(trial)
        self.flush(study)

    def flush(self, study) -> bool:
        """Send what waits; False (and the rest kept) when the server still fails."""
        while self.pending:
            try:
                self.inner(study, self.pending[0])
            except failures():
                return False
            self.pending.pop(0)
        return True
