"""`python -m launch.fly SPEC FOLDER`: fly one run of a campaign (a launch.runspec.RunSpec as JSON in
the file SPEC) into FOLDER/<its name>, as `swarm up` would, quietly and without a report. Exit
status 0 when the run completed, 1 when it failed, 2 when the spec itself is wrong. A campaign's
worker starts it as a process of its own (campaign.task), so that a timeout or a lost worker can end
the whole run: it dies with its parent (PR_SET_PDEATHSIG), and so do the swarm's processes with it
(launch.children). For a swarm, the forkserver is started as soon as the spec is read, so that it
imports what the swarm's processes run while this one imports the launcher (launch.children.warm_up)."""

from __future__ import annotations

import sys
from pathlib import Path

from bus.errors import SwarmlocError
from bus.process import die_with_parent, stop_on_signals
from launch.children import warm_up
from launch.runspec import RunSpec, resolve


def main(argv: list[str]) -> int:
    die_with_parent()
    try:
        spec = RunSpec.from_json(Path(argv[0]).read_text())
        if not spec.runner:
            warm_up()
        from bus.config import build_config

        config = build_config({**spec.config, "name": spec.name})
    except (OSError, ValueError, TypeError, SwarmlocError) as exc:
        print(f"fly: {exc}", file=sys.stderr)
        return 2
    try:
        if spec.runner:  # a computation of its own in this process, into its run directory
            run_dir = Path(argv[1]) / spec.name
            run_dir.mkdir(parents=True, exist_ok=True)
            config.dump(run_dir / "config.json")
            failures = resolve(spec.runner)(spec, config, run_dir) or []
        else:
            from launch.launcher import launch

            run_dir, failures, _ = launch(config, Path(argv[1]), show_progress=False, stop=stop_on_signals())
            if spec.report and not failures:
                _report(run_dir)
    except SwarmlocError as exc:
        print(f"fly: {spec.name}: {exc}", file=sys.stderr)
        return 1
    for failure in failures:
        print(f"fly: {spec.name}: {failure}", file=sys.stderr)
    return 1 if failures else 0


def _report(run_dir: Path) -> None:
    """The run's report; one that cannot be drawn is said in a line, the run stays complete."""
    from groundstation.report import write_report

    try:
        write_report(run_dir)
    except Exception as exc:  # a report is a view of the run, never its outcome
        print(f"fly: report of {run_dir.name} not written: {exc}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
