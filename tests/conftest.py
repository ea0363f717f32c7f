"""Fixtures shared by several test modules."""

import pytest


@pytest.fixture()
def one_torch_thread():
    """Tiny networks run fastest single-threaded; a thread pool on a busy 2-core runner costs ms per op."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
