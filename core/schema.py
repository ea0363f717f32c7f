"""Creating a database schema safely when several processes start on a new store at the same moment.

Optuna's RDB storage and MLflow's SQLAlchemy store both create or migrate their tables on first use (alembic);
two processes doing that at once on a new SQLite file collide (``IntegrityError``, "table already exists").
For SQLite files, :func:`exclusive` serialises the first use through a lock file beside the database
(``fcntl.flock``, released by the kernel when a process dies). For server databases (PostgreSQL, MySQL),
:func:`retrying` repeats a creation that lost the race: the second attempt finds the tables and only checks them.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path
from typing import Callable, Iterator, TypeVar

T = TypeVar("T")
ATTEMPTS = 5


def sqlite_file(url: str | None) -> Path | None:
    """The database file of a ``sqlite:///`` URL (None for other URLs and in-memory databases)."""
    if not url or not url.startswith("sqlite:///") or url in ("sqlite:///", "sqlite:///:memory:"):
        return None
    return Path(url.removeprefix("sqlite:///").split("?", 1)[0])


@contextlib.contextmanager
def exclusive(url: str | None) -> Iterator[None]:
    """Hold an exclusive lock on ``<database>.lock`` for a SQLite URL; no-op for any other store."""
    path = sqlite_file(url)
    if path is None:
        yield
        return
    import fcntl  # POSIX; SQLite stores shared by several processes live on one POSIX host

    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(path.name + ".lock"), "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def retrying(create: Callable[[], T], url: str | None) -> T:
    """``create()`` under :func:`exclusive`, repeated (up to ``ATTEMPTS`` times) when another process's
    concurrent schema creation made it fail."""
    from sqlalchemy.exc import SQLAlchemyError

    for attempt in range(1, ATTEMPTS + 1):
        try:
            with exclusive(url):
                return create()
        except SQLAlchemyError:
            if attempt == ATTEMPTS:
                raise
            time.sleep(0.2 * attempt)
    raise AssertionError("unreachable")
