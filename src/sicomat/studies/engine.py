"""Running a study on Dask, chunk by chunk, with nothing lost.

The variants are cut into chunks of a fixed size (the study's ``chunk_size``, else from the variant count
alone, never from the workers: the same study gives the same chunks on any cluster). Each chunk is one
Dask task (:func:`sicomat.studies.analyses.run_chunk`); the client writes each chunk's rows to
``OUT/chunks/chunk-NNNNNN.parquet`` atomically as soon as the task finishes, so an interrupted study keeps
every finished chunk, and ``resume=True`` computes only the chunks whose file is missing. The manifest
(``OUT/manifest.json``) holds the study's fingerprint (the study, the base model's text, the catalogue's
entries, the chunking and SICOMAT's version): chunks of another study are never mixed in. A worker that dies
mid-task has its task recomputed by the scheduler on another worker; its rows are written once, when a result
arrives.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
import uuid
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator

from ..errors import AnalysisError, ModelError, OutputError
from ..progress import notify

if TYPE_CHECKING:  # pragma: no cover
    import pandas

    from ..progress import ProgressCallback
    from .variants import StudyPlan

__all__ = ["run_plan", "make_folders", "chunk_size_for", "EngineRun", "CHUNK_PATTERN"]

CHUNK_PATTERN = "chunk-{:06d}.parquet"
MANIFEST = "manifest.json"


def chunk_size_for(variants: int) -> int:
    """Variants per chunk: about 64 chunks (enough to balance a few dozen workers and to lose little
    on an interruption), at most 250 variants each (a chunk's table stays small), at least one."""
    return max(1, min(250, math.ceil(variants / 64)))


@dataclass(frozen=True)
class EngineRun:
    """What the engine did: the table, the chunks computed and reused, the workers, the time."""

    table: "pandas.DataFrame"
    chunks: int
    computed: int
    reused: int
    workers: int
    scheduler: str
    elapsed_s: float
    compute_s: float


def fingerprint(plan: "StudyPlan", chunk: int) -> str:
    """The study's identity for ``resume``: what decides its chunks' rows."""
    from .. import __version__

    # what decides the chunks' rows; the Pareto objectives, the output format and the names do not
    study = plan.spec.model_dump(mode="json", exclude={"pareto", "format", "name", "description"})
    payload = {"study": study, "base": json.dumps(plan.base_data, sort_keys=True,
                                                                              default=str),
               "catalogue": catalogue_digest(), "chunk_size": chunk, "variants": plan.variants,
               "version": __version__}
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()


def catalogue_digest() -> str:
    """A digest of the catalogue entries the variants are built from (shipped, ``SICOMAT_CATALOG``, the
    ``--catalog`` folders, as the workers load them): a catalogue id in the base model or a catalogue list
    takes its values there, so a resumed study whose catalogue changed would mix rows of two catalogues.
    Every entry counts, used or not (a resume is refused rather than risked); where it was read does not."""
    from ..catalogue.resolve import default_catalogue

    entries = sorted((e.to_dict() for e in default_catalogue()), key=lambda e: (e["id"], e["kind"]))
    for entry in entries:
        entry.pop("source", None)
    return hashlib.sha256(json.dumps(entries, sort_keys=True, default=str).encode()).hexdigest()


def make_folders(out: Path) -> Path:
    """The output folder and its ``chunks/`` made (or found); an :class:`OutputError` when either is taken by
    something that is not a folder. Returns the chunks' folder."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out}: not a folder; --out names the folder that receives the study's table")
    if out.is_symlink() and not out.exists():
        raise OutputError(f"{out}: a symbolic link to {os.readlink(out)}, which does not exist; create that folder "
                          "or give --out another one")
    chunks_dir = out / "chunks"
    try:
        chunks_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{out}: cannot be created ({exc.strerror or exc})") from None
    if not chunks_dir.is_dir():
        raise OutputError(f"{chunks_dir}: not a folder; the study writes its chunks there")
    return chunks_dir


def _prepare_out(out: Path, fp: str, resume: bool, plan: "StudyPlan", chunk: int) -> set[int]:
    """The output folder ready; the chunks already on disk that ``resume`` keeps."""
    chunks_dir = make_folders(out)
    manifest = out / MANIFEST
    # what a killed client left half-written: atomic_write's temporary files (".NAME.XXXX.ext"), never read
    for leftover in [*chunks_dir.glob(".chunk-*"), *out.glob(f".{MANIFEST}.*")]:
        if leftover.is_file() and not leftover.is_symlink():
            leftover.unlink()
    done: set[int] = set()
    old = None
    if manifest.is_file():
        try:
            old = json.loads(manifest.read_text())
        except (OSError, ValueError):
            old = None
    if resume and old is not None:
        if old.get("fingerprint") != fp:
            raise ModelError("the study, its base model, the catalogue or the chunking changed since these chunks "
                             "were written; "
                             "run without --resume (recomputes everything) or give another --out",
                             source=str(manifest))
        n_chunks = math.ceil(plan.variants / chunk)
        done = {i for i in range(n_chunks) if (chunks_dir / CHUNK_PATTERN.format(i)).is_file()}
    else:   # a new study in this folder: the chunks of an earlier one go
        for stale in chunks_dir.glob("chunk-*.parquet"):
            stale.unlink()
    from ..io.atomic import atomic_write

    text = json.dumps({"fingerprint": fp, "variants": plan.variants, "chunk_size": chunk,
                       "study": plan.source, "base": str(plan.base_path)}, indent=1)
    atomic_write(manifest, lambda tmp: Path(tmp).write_text(text), kind="json")
    return done


def _chunks(plan: "StudyPlan", chunk: int, todo: list[int], threads: int | None) -> Iterator[Any]:
    from .analyses import Chunk

    from ..catalogue.resolve import user_folders

    options, folders = plan.options, tuple(str(Path(f).resolve()) for f in user_folders())
    for i in todo:
        first, stop = i * chunk, min(plan.variants, (i + 1) * chunk)
        yield Chunk(i, first, tuple(tuple(plan.settings(v)) for v in range(first, stop)), plan.base_data,
                    str(plan.base_path), options, threads, folders)


def chunk_frame(plan: "StudyPlan", first: int, rows: list[dict[str, Any]]) -> "pandas.DataFrame":
    """A chunk's table: ``variant``, the inputs, the metrics (typed), ``constraints_ok``, ``error``."""
    import numpy as np
    import pandas as pd

    from .analyses import METRICS, constraints_hold

    stop = first + len(rows)
    columns: dict[str, Any] = {"variant": np.arange(first, stop, dtype=np.int64)}
    inputs = plan.inputs(first, stop)
    for path, values in inputs.items():
        columns[path] = values if values.dtype != object else pd.array(list(values), dtype="string")
    kinds = {name: kind for analysis in plan.spec.analyses for name, kind in METRICS[analysis].items()}
    for name in plan.metrics:
        cells = [row.get(name) for row in rows]
        if kinds[name] == "b":
            columns[name] = pd.array(cells, dtype="boolean")
        else:
            columns[name] = np.array([np.nan if x is None else float(x) for x in cells], dtype=float)
    # here, where a variant's inputs meet its metrics: a constraint may read either (the workers' rows hold only
    # the metrics; a constraint on an input evaluated there never held)
    columns["constraints_ok"] = pd.array(
        [row["error"] is None and constraints_hold({**{p: v[i] for p, v in inputs.items()}, **row}, plan.constraints)
         for i, row in enumerate(rows)], dtype="boolean")
    columns["error"] = pd.array([row["error"] for row in rows], dtype="string")
    return pd.DataFrame(columns)


def run_plan(plan: "StudyPlan", out: Path, *, client: Any = None, scheduler: str | None = None,
             workers: int | None = None, resume: bool = False,
             progress: "ProgressCallback | None" = None) -> EngineRun:
    """Run every missing chunk of ``plan`` on Dask and return the whole table (sorted by variant).

    ``client``: a ``distributed.Client`` to use (left open); else ``scheduler`` (``tcp://HOST:PORT``) to
    connect to, else an embedded ``LocalCluster`` of ``workers`` processes (default: one per core), closed
    at the end."""
    import pandas as pd

    start = time.perf_counter()
    chunk = plan.spec.chunk_size or chunk_size_for(plan.variants)
    fp = fingerprint(plan, chunk)
    done = _prepare_out(out, fp, resume, plan, chunk)
    n_chunks = math.ceil(plan.variants / chunk)
    todo = [i for i in range(n_chunks) if i not in done]
    chunks_dir = out / "chunks"
    compute = 0.0
    n_workers = 0
    where = "none"
    if todo:
        notify(progress, "starting a local Dask cluster" if client is None and scheduler is None
               else "connecting to the Dask cluster", 0, None)
        with _client(client, scheduler, workers, len(todo)) as (dask_client, where, threads):
            n_workers = len(dask_client.scheduler_info().get("workers", {}))
            compute = _run(dask_client, plan, chunk, todo, threads, chunks_dir, fp, n_chunks, len(done), progress)
    else:
        notify(progress, f"study: {n_chunks} chunks already computed", n_chunks, n_chunks)
    frames = [pd.read_parquet(chunks_dir / CHUNK_PATTERN.format(i)) for i in range(n_chunks)]
    table = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    return EngineRun(table, n_chunks, len(todo), len(done), n_workers, where, time.perf_counter() - start, compute)


def _run(client: Any, plan: "StudyPlan", chunk: int, todo: list[int], threads: int | None, chunks_dir: Path,
         fp: str, n_chunks: int, reused: int, progress: "ProgressCallback | None") -> float:
    from distributed import as_completed

    from ..io.atomic import atomic_write
    from .analyses import run_chunk

    task = f"study: {plan.variants} variants in {n_chunks} chunks"
    notify(progress, task, reused, n_chunks)
    # a key of its own per run: the tasks of an interrupted run of the same study, being cancelled on the
    # scheduler, must not be taken for (and cancel) the resumed run's tasks
    run = uuid.uuid4().hex[:8]
    futures = [client.submit(run_chunk, job, key=f"sicomat-study-{fp[:12]}-{run}-{job.index}", pure=False,
                             retries=1) for job in _chunks(plan, chunk, todo, threads)]
    compute = 0.0
    finished = reused
    try:
        for future in as_completed(futures):
            try:
                result = future.result()
            except Exception as exc:  # noqa: BLE001 - a task the cluster gave up on (KilledWorker, a lost scheduler)
                raise AnalysisError(f"a chunk of the study failed on the Dask cluster ({exc.__class__.__name__}: "
                                    f"{exc}); the {finished} chunks finished are written in {chunks_dir}: run the "
                                    "same command with --resume to compute the rest") from None
            frame = chunk_frame(plan, result.index * chunk, result.rows)
            target = chunks_dir / CHUNK_PATTERN.format(result.index)
            atomic_write(target, partial(_parquet, frame), kind="parquet")
            compute += result.compute_s
            finished += 1
            future.release()
            notify(progress, task, finished, n_chunks)
    finally:
        for future in futures:
            if not future.done():
                future.cancel()
    return compute


WORKER_MEMORY = 512 * 1024 ** 2
"""Memory a worker process of the local cluster is counted to need (Python, numpy, SciPy, numba and the
compiled kernels, a chunk's models: about 300 MB measured): the default worker count leaves room for them."""


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity: a container's share, not the host's count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:   # pragma: no cover - no sched_getaffinity (macOS, Windows)
        return os.cpu_count() or 1


def default_workers(cores: int, tasks: int) -> int:
    """The local cluster's size without ``--workers``: one process per usable core, but no more than the chunks
    to compute, nor than the available memory holds at :data:`WORKER_MEMORY` each."""
    import psutil

    by_memory = int(psutil.virtual_memory().available // WORKER_MEMORY)
    return max(1, min(cores, tasks, by_memory))


def _parquet(frame: "pandas.DataFrame", path: str) -> None:
    frame.to_parquet(path, index=False)


class _client:
    """The Dask client to use: the caller's, a scheduler's by address, or an embedded local cluster."""

    def __init__(self, client: Any, scheduler: str | None, workers: int | None, tasks: int) -> None:
        self.given, self.scheduler, self.workers, self.tasks = client, scheduler, workers, tasks
        self.own: list[Any] = []
        self.levels: list[tuple[Any, int]] = []

    def __enter__(self) -> tuple[Any, str, int | None]:
        import logging

        from distributed import Client, LocalCluster

        if self.given is not None:
            return self.given, str(getattr(self.given, "scheduler", None) and self.given.scheduler.address), None
        if self.scheduler is not None:
            try:
                client = Client(self.scheduler, timeout="5s")
            except (OSError, TimeoutError) as exc:
                raise ModelError(f"cannot reach the Dask scheduler ({exc})", path="scheduler",
                                 value=self.scheduler) from None
            except ValueError as exc:      # distributed's address parsing: no port, an unknown scheme, ...
                raise ModelError(f"not a Dask scheduler address ({exc}); expected tcp://HOST:PORT", path="scheduler",
                                 value=self.scheduler) from None
            self.own.append(client)
            return client, self.scheduler, None
        cores = usable_cores()
        n = self.workers or default_workers(cores, self.tasks)
        # the scheduler runs in this process: its INFO lines (workers starting and closing) are not the
        # user's business on the terminal; the levels are put back on exit
        for name in ("distributed", "distributed.scheduler", "distributed.nanny", "distributed.core"):
            logger = logging.getLogger(name)
            self.levels.append((logger, logger.level))
            logger.setLevel(logging.ERROR)
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
        client = Client(cluster)
        self.own += [client, cluster]
        return client, "local", max(1, cores // n)

    def __exit__(self, *exc: object) -> None:
        for thing in self.own:
            try:
                thing.close()
            except Exception:  # noqa: BLE001 - closing a cluster that is going away anyway
                pass
        for logger, level in self.levels:
            logger.setLevel(level)
