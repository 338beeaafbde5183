"""An experiment stopped before its runs complete concludes nothing and says how to resume, instead of
building figures from no run (a traceback before)."""

import threading

import pytest

from bus.errors import SwarmlocError
from campaign.experiment import run_experiment
from campaign.runner import Campaign
from experiments.registry import EXPERIMENTS


def test_an_experiment_stopped_before_any_run_completes_says_so_and_how_to_resume(tmp_path):
    stop = threading.Event()
    stop.set()
    params = {p.name: p.default for p in EXPERIMENTS["cooperative"].params}
    with pytest.raises(SwarmlocError, match=r"stopped with 0 of \d+ runs complete.*same command resumes"):
        run_experiment("cooperative", params, tmp_path, Campaign(workers=1), stop=stop)
