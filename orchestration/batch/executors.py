"""Executors: a pool of worker processes on this machine (a worker that dies costs only its case) or a
Dask cluster."""

from __future__ import annotations

import multiprocessing
import os
import signal
import tempfile
from collections import deque
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

from .config import BatchConfigError
from .worker import crashed_record, dask_run, isolated_main, run_case, worker_init


class LocalPool:
    """Cases in a pool of worker processes on this machine; a dead worker costs only its case."""

    def __init__(self, workers: Optional[int] = None, mp_context=None) -> None:
        self.workers = max(1, workers or os.cpu_count() or 1)
        self.context = (
            multiprocessing.get_context(mp_context) if isinstance(mp_context, str) or mp_context is None else mp_context
        )
        self.restarts = 0
        self._tmp: Optional[str] = None  # the workers' temporary folder while a batch runs

    def _pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.workers, mp_context=self.context, initializer=worker_init, initargs=(self._tmp,)
        )

    def run(self, tasks: Sequence[dict], on_result: Callable[[dict], None]) -> None:
        # workers are stopped, not asked to clean up: what they extract goes to a folder removed here
        with tempfile.TemporaryDirectory(prefix="mast_batch_") as tmp:
            self._tmp = tmp
            try:
                self._run(tasks, on_result)
            finally:
                self._tmp = None

    def _run(self, tasks: Sequence[dict], on_result: Callable[[dict], None]) -> None:
        queue = deque(tasks)
        pool = self._pool()
        running: dict = {}
        try:
            while queue or running:
                suspects = []
                while queue and len(running) < self.workers:  # no backlog: a crash has few suspects
                    try:
                        running[pool.submit(run_case, queue[0])] = queue[0]
                    except BrokenProcessPool:  # a worker died since the last look: recover below
                        break
                    queue.popleft()
                done, _ = wait(running, return_when=FIRST_COMPLETED) if running else (set(), set())
                for future in done:
                    task = running.pop(future)
                    try:
                        record = future.result()
                    except BrokenProcessPool:
                        suspects.append(task)
                        continue
                    except Exception as err:  # e.g. a task that could not be pickled
                        record = {**crashed_record(task, f"{type(err).__name__}: {err}"), "status": "failed"}
                    on_result(record)
                if suspects or getattr(pool, "_broken", False):
                    # a worker died and took the pool with it: every case that was running is a suspect;
                    # each runs again alone, so only the one that crashes is recorded as crashed
                    for future, task in running.items():
                        if future.done() and not future.cancelled() and future.exception() is None:
                            on_result(future.result())  # finished just before the crash: keep it
                        else:
                            suspects.append(task)
                    running.clear()
                    self._stop(pool)
                    for task in suspects:
                        on_result(self._isolated(task))
                    pool = self._pool()
                    self.restarts += 1
        finally:
            self._stop(pool)

    def _isolated(self, task: dict) -> dict:
        reader, writer = self.context.Pipe(duplex=False)
        fd, fault_file = tempfile.mkstemp(prefix="mast_batch_fault_", suffix=".txt")
        os.close(fd)
        proc = self.context.Process(target=isolated_main, args=(task, writer, fault_file, self._tmp), daemon=True)
        proc.start()
        writer.close()
        record = None
        try:
            while record is None:
                if reader.poll(0.05):
                    try:
                        record = reader.recv()
                    except EOFError:
                        break
                elif not proc.is_alive():
                    if reader.poll(0):
                        continue
                    break
        finally:
            proc.join(5)
            if proc.is_alive():
                proc.kill()
                proc.join()
            reader.close()
            try:
                stack = Path(fault_file).read_text(errors="replace").strip().splitlines()
            finally:
                os.unlink(fault_file)
        if record is None:
            where = ""
            if stack:
                where = "; Python stack at the crash (most recent call first):\n" + "\n".join(stack[:12])
            return crashed_record(
                task, f"the worker process died ({_exit_text(proc.exitcode)}) while running this case{where}"
            )
        return record

    @staticmethod
    def _stop(pool: ProcessPoolExecutor) -> None:
        processes = list(getattr(pool, "_processes", {}).values())  # no public way to stop running workers
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in processes:
            if proc.is_alive():
                proc.terminate()
        for proc in processes:
            proc.join(5)


def _exit_text(code: Optional[int]) -> str:
    if code is None:
        return "exit code unknown"
    if code < 0:
        try:
            return f"killed by signal {-code}, {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


class DaskCluster:
    """Cases on an existing Dask distributed cluster (a scheduler address or a Client)."""

    def __init__(self, scheduler) -> None:
        try:
            from distributed import Client
        except ModuleNotFoundError:
            raise RuntimeError("--scheduler needs Dask distributed: pip install 'mast-cosim[batch]'") from None
        self._own = not isinstance(scheduler, Client)
        self.client = Client(scheduler) if self._own else scheduler

    def run(self, tasks: Sequence[dict], on_result: Callable[[dict], None]) -> None:
        from distributed import as_completed

        try:
            from distributed.scheduler import KilledWorker
        except ImportError:  # moved between releases
            from distributed import KilledWorker
        blobs: dict[str, Any] = {}
        for task in tasks:
            if Path(task["ssp_path"]).suffix == ".ssd":
                raise BatchConfigError(
                    f"{task['ssp_path']}: on a cluster, give a built .ssp (the workers get the "
                    "archive; an .ssd's FMUs and parameter files stay behind)"
                )
            if task["ssp_sha"] not in blobs:
                blobs[task["ssp_sha"]] = self.client.scatter(
                    Path(task["ssp_path"]).read_bytes(), broadcast=True, hash=False
                )
        token = os.urandom(4).hex()
        futures = {
            self.client.submit(
                dask_run, task, blobs[task["ssp_sha"]], key=f"mast-{task['id']}-{token}", pure=False, retries=0
            ): task
            for task in tasks
        }
        try:
            for future in as_completed(futures):
                task = futures[future]
                try:
                    record = future.result()
                except KilledWorker as err:
                    record = crashed_record(task, f"the Dask worker running this case died ({err})")
                except Exception as err:
                    record = {**crashed_record(task, f"{type(err).__name__}: {err}"), "status": "failed"}
                future.release()
                on_result(record)
        finally:
            for future in futures:
                if not future.done():
                    future.cancel()
            if self._own:
                self.client.close()
