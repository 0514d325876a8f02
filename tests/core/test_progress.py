"""pasta.core.progress: reports reach every listener of the block that made them, and nobody else."""

from pasta.core import progress


def test_reports_reach_nested_listeners_and_stop_at_the_end_of_their_block():
    outer, inner = [], []
    progress.report("optimise", 1, 10)  # nobody listens: nothing happens
    assert not progress.active()
    with progress.listening(outer.append):
        progress.report("optimise", 1, 10, best_score=0.5)
        with progress.listening(inner.append):
            assert progress.active()
            progress.report("refine", 2, 5)
        progress.report("optimise", 3, 10)
    progress.report("optimise", 4, 10)
    assert [(e.stage, e.done, e.total) for e in outer] == [("optimise", 1, 10), ("refine", 2, 5), ("optimise", 3, 10)]
    assert [(e.stage, e.done) for e in inner] == [("refine", 2)]
    assert outer[0].info == {"best_score": 0.5}


def test_the_latent_optimiser_reports_every_iteration_of_each_round():
    import torch

    from pasta.planning import LatentPlannerConfig, search
    from pasta.testing import analytic_problem

    problem = analytic_problem(horizon=2)
    events = []
    with progress.listening(events.append):
        search(problem, [("split", "move")], LatentPlannerConfig(num_samples=8, iterations=5), torch.Generator().manual_seed(0))
    assert [(e.stage, e.done, e.total) for e in events] == [("optimise", i, 5) for i in range(6)]
    assert all(e.info["samples"] > 0 and isinstance(e.info["best_score"], float) for e in events)


def test_bars_are_drawn_on_a_terminal_only(monkeypatch):
    import io
    import sys

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert not progress.on_terminal()  # a pipe or a log file: no bar
    monkeypatch.setattr(sys, "stderr", Terminal())
    assert progress.on_terminal() and not progress.on_terminal(False)  # progress=false
