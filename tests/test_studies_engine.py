"""The study engine on real Dask worker processes (issue 14, "nothing lost"): the table does not depend on the
number of workers; a worker killed mid-study loses no row and duplicates none; an interrupted study resumes
and computes only the missing chunks; a resumed study that changed is refused.

Each test starts a ``LocalCluster`` of worker processes on loopback; every wait is bounded (the test fails
rather than hangs)."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from sicomat.errors import ModelError

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

STUDY = """
base = "paper_5m4s.toml"
seed = 11
analyses = ["modal", "margins", "simulate"]
chunk_size = {chunk}
constraints = ["margins.velocity.phase_margin_deg >= 30"]

[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
distribution = "uniform"
low = 0.8
high = 1.2
relative = true
samples = 24

[[parameters]]
path = "axes.X.controller.Kv"
values = ["20 1/s", "30 1/s"]

[simulate]
duration = "0.4 s"
"""

BOUND_S = 240.0
"""Longest wait for a study of these tests (they take seconds; the bound only turns a hang into a failure)."""


def write(folder: Path, chunk: int = 3) -> Path:
    (folder / "paper_5m4s.toml").write_text((EXAMPLES / "paper_5m4s.toml").read_text())
    path = folder / "study.toml"
    path.write_text(STUDY.format(chunk=chunk))
    return path


def cluster(n: int):
    import logging

    from distributed import Client, LocalCluster

    c = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                     silence_logs=logging.ERROR)
    return c, Client(c)


def bounded(fn, seconds: float = BOUND_S):
    """Run ``fn`` in a thread; its result, or a failure if it has not returned within ``seconds``."""
    out: dict = {}

    def target():
        try:
            out["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - re-raised in the test's thread
            out["error"] = exc

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"the study did not finish within {seconds} s"
    if "error" in out:
        raise out["error"]
    return out["value"]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The study's table on one worker process."""
    from sicomat.studies import Study

    folder = tmp_path_factory.mktemp("one")
    c, client = cluster(1)
    try:
        results = bounded(lambda: Study(write(folder)).run(client))
    finally:
        client.close()
        c.close()
    table = results.to_pandas()
    assert len(table) == 48 and table["error"].isna().all()
    return table


def test_two_worker_processes_give_the_same_table(tmp_path, reference):
    """Bit for bit: the chunks are fixed by the variant count, and a variant's numbers do not depend on
    which process, or which batch, computed them."""
    from sicomat.studies import Study

    c, client = cluster(2)
    try:
        results = bounded(lambda: Study(write(tmp_path)).run(client))
        workers = set(client.scheduler_info()["workers"])
    finally:
        client.close()
        c.close()
    assert len(workers) == 2
    pd.testing.assert_frame_equal(results.to_pandas(), reference)


def test_a_killed_worker_loses_no_row_and_duplicates_none(tmp_path, reference):
    """SIGKILL one of two worker processes once the first chunk is written (48 chunks of one variant, about a
    second of work: the kill lands while both are computing): the scheduler recomputes the lost task elsewhere (the nanny restarts the
    worker); every variant is in the table once, with the reference's numbers (which were cut in chunks of 3:
    the chunking does not change a number either)."""
    from sicomat.studies import Study

    c, client = cluster(2)
    results: list = []
    try:
        pids = client.run(os.getpid)
        study = Study(write(tmp_path, chunk=1))
        runner = threading.Thread(target=lambda: results.append(study.run(client)), daemon=True)
        runner.start()
        chunks = study.out / "chunks"
        deadline = time.monotonic() + BOUND_S
        while time.monotonic() < deadline and not any(chunks.glob("chunk-*.parquet")):
            time.sleep(0.01)
        os.kill(sorted(pids.values())[0], signal.SIGKILL)
        written_at_kill = len(list(chunks.glob("chunk-*.parquet")))
        runner.join(BOUND_S)
        assert not runner.is_alive(), "the study did not finish after the worker was killed"
        after = client.run(os.getpid)
    finally:
        client.close()
        c.close()
    assert 1 <= written_at_kill < 48, "the kill must land mid-study"
    assert sorted(pids.values())[0] not in after.values()     # the process was killed (and replaced)
    table = results[0].to_pandas()
    assert list(table["variant"]) == list(range(48))          # none lost, none twice
    pd.testing.assert_frame_equal(table, reference)


def test_an_interrupted_study_resumes_with_only_the_missing_chunks(tmp_path, reference):
    """Ctrl-C after three chunks (raised from the progress callback, in the client's thread as a real Ctrl-C
    is): the finished chunks stay on disk; --resume computes the other thirteen and leaves the first ones
    untouched (same bytes, same modification time); the table is the uninterrupted study's."""
    from sicomat.studies import Study

    path = write(tmp_path)
    c, client = cluster(1)
    try:
        def stop_after_three(task, done, total):
            if total is not None and done >= 3:
                raise KeyboardInterrupt

        with pytest.raises(KeyboardInterrupt):
            bounded(lambda: Study(path).run(client, progress=stop_after_three))
        chunks = tmp_path / "study.results" / "chunks"
        kept = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in chunks.glob("chunk-*.parquet")}
        assert len(kept) == 3 and not (tmp_path / "study.results" / "results.parquet").exists()
        results = bounded(lambda: Study(path).run(client, resume=True))
    finally:
        client.close()
        c.close()
    assert results.info["chunks"] == {"total": 16, "computed": 13, "reused": 3}
    for name, (mtime, data) in kept.items():
        assert (chunks / name).stat().st_mtime_ns == mtime and (chunks / name).read_bytes() == data
    pd.testing.assert_frame_equal(results.to_pandas(), reference)


def test_a_killed_client_leaves_no_process_and_resumes(tmp_path, reference):
    """SIGKILL the `sicomat study` process itself (client, scheduler and the local cluster's nanny in it) once a
    chunk is written: its worker processes do not outlive it (they lose their scheduler and stop), the chunks on
    disk are whole (a chunk is renamed into place complete; a temporary file the kill left is removed at the
    resume), and --resume computes only the missing chunks, giving the uninterrupted study's table."""
    import subprocess
    import sys

    import psutil

    from sicomat.studies import Study

    path = write(tmp_path, chunk=1)
    chunks = tmp_path / "study.results" / "chunks"
    proc = subprocess.Popen([sys.executable, "-c", "from sicomat.cli.main import main; main()", "study", str(path),
                             "--workers", "1", "--no-figures"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + BOUND_S
        while time.monotonic() < deadline and not any(chunks.glob("chunk-*.parquet")) and proc.poll() is None:
            time.sleep(0.01)
        children = psutil.Process(proc.pid).children(recursive=True)
        proc.kill()
    finally:
        proc.wait(BOUND_S)
    gone, alive = psutil.wait_procs(children, timeout=60)
    for p in alive:      # not to leave them to the next tests; the assertion below fails
        p.kill()
    assert not alive, f"worker processes outlived the killed client: {[p.pid for p in alive]}"
    (chunks / ".chunk-000047.parquet.abc123.parquet").write_bytes(b"PAR1 cut short by a kill")
    written = len(list(chunks.glob("chunk-*.parquet")))
    assert 1 <= written < 48, "the kill must land mid-study"
    with inprocess_client() as client:
        results = bounded(lambda: Study(path).run(client, resume=True))
    assert results.info["chunks"] == {"total": 48, "computed": 48 - written, "reused": written}
    assert not list(chunks.glob(".chunk-*"))
    pd.testing.assert_frame_equal(results.to_pandas(), reference)


def inprocess_client():
    """An in-process client with one single-threaded worker (the tests that need no worker processes)."""
    from distributed import Client

    return Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0")


def test_resuming_a_changed_study_is_refused(tmp_path, reference):
    from distributed import Client

    from sicomat.studies import Study

    path = write(tmp_path)
    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as client:
        bounded(lambda: Study(path).run(client))
        path.write_text(path.read_text().replace("seed = 11", "seed = 12"))
        with pytest.raises(ModelError, match="changed since these chunks were written"):
            Study(path).run(client, resume=True)
        # without --resume the folder is the new study's: its old chunks go
        results = bounded(lambda: Study(path).run(client))
    assert results.info["chunks"]["reused"] == 0
    assert not results.to_pandas()["axes.X.mechanics.bodies.load.mass"].equals(
        reference["axes.X.mechanics.bodies.load.mass"])


def test_resuming_after_the_catalogue_changed_is_refused(tmp_path, monkeypatch):
    """A catalogue id in the base model takes its values from the catalogue: the chunks written before a
    catalogue entry changed hold the old motor's rows, so --resume refuses (the study file and the model file
    are unchanged); with the entry as it was, the resume goes on and reuses them."""
    from distributed import Client

    from sicomat.catalogue.resolve import use_folders
    from sicomat.studies import Study

    monkeypatch.delenv("SICOMAT_CATALOG", raising=False)
    parts = tmp_path / "parts"
    parts.mkdir()
    motor = parts / "servo-motor-400v-6nm.toml"
    entry = ('kind = "motor"\n[parameters]\nrotor_inertia = "{}"\ntorque_constant = "1.6 N*m/A"\n'
             'torque_constant_basis = "rms"\n[provenance]\nsource = "typical"\nrange = "a test entry"\n')
    motor.write_text(entry.format("70 kg*cm^2"))
    (tmp_path / "ballscrew_catalog.toml").write_text((EXAMPLES / "ballscrew_catalog.toml").read_text())
    study = tmp_path / "study.toml"
    study.write_text('base = "ballscrew_catalog.toml"\nanalyses = ["modal"]\nchunk_size = 1\n[[parameters]]\n'
                     'path = "axes.X.mechanics.parts.4.mass"\nvalues = ["250 kg", "300 kg"]\n')
    use_folders([str(parts)])
    try:
        with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as client:
            first = bounded(lambda: Study(study).run(client))
            motor.write_text(entry.format("80 kg*cm^2"))
            with pytest.raises(ModelError, match="the catalogue or the chunking changed"):
                Study(study).run(client, resume=True)
            motor.write_text(entry.format("70 kg*cm^2"))
            again = bounded(lambda: Study(study).run(client, resume=True))
    finally:
        use_folders([])
    assert again.info["chunks"] == {"total": 2, "computed": 0, "reused": 2}
    pd.testing.assert_frame_equal(again.to_pandas(), first.to_pandas())


def test_the_catalog_folders_of_the_command_line_reach_the_worker_processes(tmp_path, monkeypatch):
    """``sicomat --catalog DIR study``: the workers (other processes, without the client's state) build each
    variant with the folder's motor, as ``sicomat --catalog DIR modal`` does in one process."""
    import json

    from typer.testing import CliRunner

    from sicomat.cli.main import app

    monkeypatch.delenv("SICOMAT_CATALOG", raising=False)
    parts = tmp_path / "parts"
    parts.mkdir()
    (parts / "servo-motor-400v-6nm.toml").write_text(   # ten times the shipped rotor inertia
        'kind = "motor"\n[parameters]\nrotor_inertia = "70 kg*cm^2"\ntorque_constant = "1.6 N*m/A"\n'
        'torque_constant_basis = "rms"\n[provenance]\nsource = "typical"\nrange = "a test entry"\n')
    (tmp_path / "ballscrew_catalog.toml").write_text((EXAMPLES / "ballscrew_catalog.toml").read_text())
    study = tmp_path / "study.toml"
    study.write_text('base = "ballscrew_catalog.toml"\nanalyses = ["modal"]\n[[parameters]]\n'
                     'path = "axes.X.mechanics.parts.4.mass"\nvalues = ["250 kg"]\n')
    runner = CliRunner()
    try:
        modal = runner.invoke(app, ["--catalog", str(parts), "modal", str(tmp_path / "ballscrew_catalog.toml"),
                                    "--json"])
        shipped = runner.invoke(app, ["modal", str(tmp_path / "ballscrew_catalog.toml"), "--json"])
        result = runner.invoke(app, ["--catalog", str(parts), "study", str(study), "--json", "--workers", "1",
                                     "--no-figures"])
    finally:
        from sicomat.catalogue.resolve import use_folders

        use_folders([])
    assert result.exit_code == 0, result.output
    first = [f for f in json.loads(modal.stdout)["undamped_hz"] if f > 0][0]
    first_shipped = [f for f in json.loads(shipped.stdout)["undamped_hz"] if f > 0][0]
    table = pd.read_parquet(json.loads(result.stdout)["results"])
    assert table["modal.f1_hz"][0] == pytest.approx(first, rel=1e-12)     # the same model, the same arithmetic
    assert abs(first - first_shipped) > 1e-3 * first_shipped              # and not the shipped motor's


def test_an_existing_cluster_by_its_address(tmp_path, reference):
    """``--scheduler tcp://HOST:PORT``: the same table on a cluster started elsewhere; an address nobody
    answers at is one line and exit status 2 (after the client's 5 s connection timeout)."""
    import json

    from typer.testing import CliRunner

    from sicomat.cli.main import app

    runner = CliRunner()
    c, client = cluster(1)
    try:
        result = bounded(lambda: runner.invoke(app, ["study", str(write(tmp_path)), "--scheduler",
                                                     c.scheduler_address, "--json", "--no-figures"]))
    finally:
        client.close()
        c.close()
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert payload["scheduler"] == c.scheduler_address and payload["workers"] == 1
    pd.testing.assert_frame_equal(pd.read_parquet(payload["results"]), reference)
    result = bounded(lambda: runner.invoke(app, ["study", str(write(tmp_path)), "--scheduler", "tcp://127.0.0.1:9",
                                                 "--no-figures"]), 60)
    assert result.exit_code == 2 and "--scheduler" in result.output and "tcp://127.0.0.1:9" in result.output
    assert "Traceback" not in result.output
