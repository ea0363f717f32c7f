"""Fixtures shared by several test modules."""

import os

import pytest


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
