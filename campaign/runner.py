"""Run a list of runs (launch.runspec) as a campaign on Dask: each run one task (campaign.task), at most
one per unit of the ``swarm`` worker resource, rows written as runs finish, the results table at the
end. A campaign folder that already holds finished runs resumes: complete runs are skipped, failed
and missing ones flown again. A run that fails on its own is a row with status ``failed`` and is not
retried; a task whose worker is lost is rescheduled by Dask on another worker (an infrastructure
failure). Ctrl-C (``stop``) cancels what is left and leaves nothing running."""

from __future__ import annotations

import io
import json
import tarfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from campaign.cluster import RESOURCE, connect
from campaign.rows import ROW_FILE
from campaign.table import done_rows, write_table
from launch.runspec import RunSpec, check_unique

SPECS_FILE = "campaign.json"


@dataclass
class Progress:
    """What the campaign has done so far, for a progress line."""

    total: int
    done: int = 0
    failed: int = 0
    skipped: int = 0
    started: float = field(default_factory=time.monotonic)
    dashboard: str | None = None

    def line(self, running: int) -> str:
        flown = self.done + self.failed
        elapsed = time.monotonic() - self.started
        left = self.total - self.skipped - flown
        eta = f", about {elapsed / flown * left:.0f} s left" if flown and left else ""
        return (
            f"campaign: {self.done + self.skipped} done ({self.skipped} from before), {running} running, "
            f"{self.failed} failed, of {self.total}{eta}"
        )


@dataclass(frozen=True)
class Campaign:
    """Where and how: ``scheduler`` (None: a local cluster of ``workers``, default from the cores and
    ``cpu_per_run``), each run's wall-clock ``timeout_s``, and whether the workers see the campaign
    folder (a local cluster does; a cluster does when ``shared``)."""

    scheduler: str | None = None
    workers: int | None = None
    cpu_per_run: float = 2.0
    timeout_s: float = 1800.0
    shared: bool = False


def run_campaign(
    specs: list[RunSpec],
    folder: Path,
    how: Campaign,
    *,
    stop: threading.Event,
    say: Callable[[str], None] = lambda text: None,
) -> list[dict[str, Any]]:
    """Fly every run of ``specs`` into ``folder`` (resuming what is there); the rows in ``specs``'
    order (runs stopped before they finished have none). Writes ``results.parquet``."""
    check_unique(specs)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / SPECS_FILE).write_text(json.dumps([json.loads(s.to_json()) for s in specs], indent=1) + "\n")
    rows = done_rows(folder, specs)
    todo = [s for s in specs if s.name not in rows]
    progress = Progress(total=len(specs), skipped=len(rows))
    if todo and not stop.is_set():
        _fly(todo, folder, how, rows, progress, stop, say)
    write_table(folder, specs, rows)
    return [rows[s.name] for s in specs if s.name in rows]


def _fly(
    todo: list[RunSpec],
    folder: Path,
    how: Campaign,
    rows: dict[str, dict[str, Any]],
    progress: Progress,
    stop: threading.Event,
    say: Callable[[str], None],
) -> None:
    from distributed import as_completed

    from campaign.task import fly

    shared = how.scheduler is None or how.shared
    with connect(how.scheduler, how.workers, how.cpu_per_run) as client:
        progress.dashboard = getattr(client, "dashboard_link", None)
        if progress.dashboard:
            say(f"campaign: Dask dashboard {progress.dashboard}")
        futures = {
            client.submit(
                fly,
                spec.to_json(),
                str(folder.resolve()),
                folder.name,
                how.timeout_s,
                shared,
                key=f"{folder.name}/{spec.name}",
                resources={RESOURCE: 1},
                pure=False,
                retries=0,
            ): spec
            for spec in todo
        }
        pending = set(futures)
        say(progress.line(min(len(pending), _slots(client))))
        completed = as_completed(futures, with_results=False)
        while pending:
            if stop.is_set():
                client.cancel(list(pending))
                say(f"campaign: stopped; {len(pending)} runs not flown (the same command resumes)")
                return
            batch = completed.next_batch(block=False) if completed.has_ready() else []
            if not batch:
                time.sleep(0.2)
                continue
            for future in batch:
                pending.discard(future)
                spec = futures[future]
                row = _row(future, spec, folder)
                rows[spec.name] = row
                progress.done += row["status"] == "complete"
                progress.failed += row["status"] != "complete"
                say(f"  {spec.name}: {row['status']}{' (' + row['exit_reason'] + ')' if row['exit_reason'] else ''}")
            say(progress.line(min(len(pending), _slots(client))))


def _row(future: Any, spec: RunSpec, folder: Path) -> dict[str, Any]:
    """A finished task's row (its run directory unpacked here when it travelled); a task that raised
    (its workers lost too often, Dask's ``allowed-failures``) is a failed row."""
    try:
        row = future.result()
    except Exception as exc:  # a lost worker, a killed task: an infrastructure failure, reported
        return {"run": spec.name, "variant": spec.variant, "seed": spec.seed, "status": "failed",
                "exit_reason": f"{type(exc).__name__}: {exc}"[:500]}  # fmt: skip
    archive = row.pop("_archive", None)
    if archive is not None:
        with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
            tar.extractall(folder, filter="data")
    (folder / spec.name).mkdir(parents=True, exist_ok=True)
    (folder / spec.name / ROW_FILE).write_text(json.dumps(row, sort_keys=True, indent=1) + "\n")
    return row


def _slots(client: Any) -> int:
    """How many runs the cluster flies at once (its workers' ``swarm`` resources)."""
    try:
        info = client.scheduler_info()["workers"].values()
    except Exception:  # a scheduler that went away: the count is only for the progress line
        return 1
    return max(1, int(sum(w.get("resources", {}).get(RESOURCE, 0) for w in info)))
