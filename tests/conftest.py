"""Fixtures shared by several test modules."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


class Cli:
    """The ``thermodrift`` command as a user runs it: a subprocess of this interpreter.

    ``exe`` is the command line to extend with a verb and its arguments; ``env()`` this process's environment with
    MLflow's telemetry off and no inherited sweep id (every invocation makes its own); calling the object runs one
    command to its end in ``cwd`` and returns the completed process with its stdout and stderr as text."""

    exe = [sys.executable, "-m", "thermodrift.core.cli"]

    @staticmethod
    def env(**extra: str) -> dict[str, str]:
        env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true", **extra}
        env.pop("THERMODRIFT_SWEEP_ID", None)
        return env

    def __call__(self, cwd, *args: str, timeout: float = 600, env: dict | None = None,
                 stdin: str | None = None) -> subprocess.CompletedProcess:
        return subprocess.run([*self.exe, *args], cwd=cwd, env=self.env(**(env or {})), capture_output=True,
                              text=True, timeout=timeout, input=stdin)


@pytest.fixture(scope="session")
def cli() -> Cli:
    """Runs ``thermodrift`` in a subprocess (:class:`Cli`)."""
    return Cli()


@pytest.fixture()
def one_torch_thread():
    """Tiny networks run fastest single-threaded; a thread pool on a busy 2-core runner costs ms per op."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture()
def postgres_url() -> str:
    """The PostgreSQL server that ``bash .ci/run`` starts (.ci/postgres.sh); required there, optional elsewhere."""
    url = os.environ.get("THERMODRIFT_TEST_POSTGRES")
    if url:
        return url
    if os.environ.get("THERMODRIFT_REQUIRE_POSTGRES"):
        pytest.fail("THERMODRIFT_TEST_POSTGRES is not set although .ci/run starts a PostgreSQL server")
    pytest.skip("no PostgreSQL server: run `bash .ci/run`, or set THERMODRIFT_TEST_POSTGRES to a SQLAlchemy URL")


@pytest.fixture(scope="session")
def empty_mlflow_db(tmp_path_factory) -> Path:
    """An MLflow SQLite database with its schema and nothing else, made once per test process: MLflow migrates a
    new database through its whole schema history, about a second of CPU that every scratch folder would repeat."""
    import mlflow

    path = tmp_path_factory.mktemp("mlflow_template") / "mlflow.db"
    mlflow.MlflowClient(f"sqlite:///{path}").search_experiments()  # creates the schema, idle afterwards
    return path


@pytest.fixture()
def workdir(tmp_path, empty_mlflow_db):
    """A scratch folder as a user's working folder: the tiny recording (seed 0) as ``tiny.csv`` + ``tiny.yaml``
    (``dataset=recording_file dataset.params.table=tiny.csv dataset.params.manifest=tiny.yaml`` reads it) and an
    empty ``mlflow.db`` (a copy of :func:`empty_mlflow_db`)."""
    from thermodrift.testing.data import tiny_recording

    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    shutil.copy(empty_mlflow_db, tmp_path / "mlflow.db")
    return tmp_path
