"""Importing thermodrift's libraries must not pay for torch (seconds): only training and prediction import it."""

import subprocess
import sys

import pytest


@pytest.mark.parametrize("module", ["thermodrift.testing", "thermodrift.core.study"])
def test_importing_does_not_import_torch(module):
    code = f"import sys; import {module}; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False"], f"importing {module} imported torch"


def test_a_job_still_sets_torch_threads():
    """The thread count of a spec reaches torch once a job runs (torch imported there, not at import)."""
    code = ("import sys; from thermodrift.core.study import Job, JobSpec; "
            "from thermodrift.testing import tiny_recording; "
            "Job(JobSpec(dataset='x', model='mlr', split='chronological', n_trials=0, storage=None, progress=False, "
            "threads=2)).run(tiny_recording()); import torch; print(torch.get_num_threads())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out[-1] == "2"
