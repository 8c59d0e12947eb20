"""Local execution: the tasks in this process (`workers=1`) or in N spawned worker processes, one pipe each.

The tasks are first cut into units (`eval.execution.batches.plan_units`: batches of kinematic episodes that
share a vector env, and single episodes); units, not episodes, are dealt round-robin to the workers (worker i
runs units i, i + N, ...). Results do not depend on the dealing: every episode starts from its own seeds. A
worker that dies marks its unfinished episodes failed."""

from __future__ import annotations

import os
import pickle
import signal
import threading

from eval.config import EvalConfig
from eval.execution.batches import UnitRunner, plan_units
from eval.execution.tasks import ExecutionInterrupted, Task, failed_record, keep_arrays


def _worker_main(wid: int, config: EvalConfig, user_bytes: bytes | None, units: list[list[Task]], out) -> None:
    """Entry point of one worker process: run `units` in order, send each episode's result through the pipe
    `out` as it ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group: the parent stops us
    user = pickle.loads(user_bytes) if user_bytes else {}
    runner = UnitRunner(config, user)
    try:
        for unit in units:
            for task, rec, arrays in runner.run(unit):
                out.send(("result", task.index, rec, arrays if keep_arrays(config, task) else None))
    finally:
        runner.close()
        out.send(("done", wid, None, None))
        out.close()


def execute_local(
    config: EvalConfig, user: dict, tasks: list[Task], user_bytes: bytes | None = None, on_result=None
) -> tuple[dict[int, dict], dict[int, dict]]:
    """Run `tasks` in this process (workers=1) or in spawned worker processes; returns ({index: record}, {index: arrays}). `on_result(record)` is called as each ends."""
    records: dict[int, dict] = {}
    arrays: dict[int, dict] = {}

    def take(index, rec, arr):
        if on_result is not None:  # first: a record whose journaling was interrupted is not returned either
            on_result(rec)
        records[index] = rec
        if arr is not None:
            arrays[index] = arr

    units = plan_units(config, user, tasks)
    n_workers = min(config.workers, len(units))
    if n_workers <= 1:
        runner = UnitRunner(config, user)
        try:
            for unit in units:
                for task, rec, arr in runner.run(unit):
                    take(task.index, rec, arr if keep_arrays(config, task) else None)
        except KeyboardInterrupt:
            raise ExecutionInterrupted(records, arrays) from None
        finally:
            runner.close()
        return records, arrays
    _execute_workers(config, user_bytes, tasks, units, n_workers, records, arrays, take)
    return records, arrays


def _execute_workers(
    config: EvalConfig,
    user_bytes,
    tasks: list[Task],
    units: list[list[Task]],
    n_workers: int,
    records: dict,
    arrays: dict,
    take,
) -> None:
    """The units dealt round-robin to `n_workers` spawned processes. The workers ignore SIGINT (they are
    spawned with it ignored): on Ctrl-C (or SIGTERM, which the CLI turns into one) this process takes what they
    sent, terminates them and raises `ExecutionInterrupted`."""

    import multiprocessing as mp
    from multiprocessing.connection import wait

    # one pipe per worker: send() is synchronous, so a result sent before a crash is never lost
    ctx = mp.get_context("spawn")
    shares = [units[i::n_workers] for i in range(n_workers)]
    readers, procs = [], []
    with _single_threaded_children(), _ignored(signal.SIGINT):  # not SIGTERM: terminate() must stop them
        for i in range(n_workers):
            r, w = ctx.Pipe(duplex=False)
            p = ctx.Process(
                target=_worker_main,
                args=(i, config, user_bytes, shares[i], w),
                daemon=True,
                name=f"mobman-eval-worker-{i}",
            )
            p.start()
            w.close()  # the parent keeps only the read end: EOF when the worker is gone
            readers.append(r)
            procs.append(p)
    active = set(range(n_workers))
    try:
        while active:
            wait([readers[i] for i in active] + [procs[i].sentinel for i in active])
            for i in sorted(active):
                if _read_available(readers[i], take):
                    active.discard(i)  # said "done"
                elif not procs[i].is_alive():
                    _read_available(readers[i], take)
                    procs[i].join()
                    active.discard(i)
                    message = (
                        f"worker process {procs[i].pid} died with exit code {procs[i].exitcode} (its error is on "
                        f"stderr; a script that calls eval.run with workers > 1 needs an "
                        f"`if __name__ == '__main__':` guard)"
                    )
                    for t in (t for unit in shares[i] for t in unit):
                        if t.index not in records:
                            take(t.index, failed_record(t, message), None)
    except KeyboardInterrupt:
        with _ignored(signal.SIGINT, signal.SIGTERM):
            for i in active:  # what was sent before Ctrl-C is kept
                _read_available(readers[i], take)
            for p in procs:
                p.terminate()
            for p in procs:
                p.join(timeout=5)
        raise ExecutionInterrupted(records, arrays) from None
    except BaseException:  # e.g. the journal could not be written: stop the workers now, not after their units
        for p in procs:
            p.terminate()
        raise
    finally:
        for p in procs:
            p.join(timeout=10)
            if p.is_alive():
                p.terminate()
        for r in readers:
            r.close()
    for t in tasks:  # a worker that stopped early (it reports its own error on stderr)
        if t.index not in records:
            take(t.index, failed_record(t, "the worker process stopped before running this episode"), None)


#: Thread-pool sizes for worker processes: one process per core is the parallelism; BLAS / OpenMP thread pools
#: on top of it would only oversubscribe the cores.
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


class _single_threaded_children:
    """Set the thread-pool variables to 1 (unless the user set them) while worker processes are spawned."""

    def __enter__(self):
        self._saved = {k: os.environ.get(k) for k in _THREAD_VARS}
        for k in _THREAD_VARS:
            os.environ.setdefault(k, "1")

    def __exit__(self, *exc):
        for k, v in self._saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class _ignored:
    """Ignore the signals `signums` inside the block (processes spawned in it start with them ignored); main
    thread only."""

    def __init__(self, *signums: int) -> None:
        self.signums = signums

    def __enter__(self):
        self._main = threading.current_thread() is threading.main_thread()
        if self._main:
            self._previous = {s: signal.signal(s, signal.SIG_IGN) for s in self.signums}

    def __exit__(self, *exc):
        if self._main:
            for s, handler in self._previous.items():
                signal.signal(s, handler)


def _read_available(conn, take) -> bool:
    """Take every message waiting on `conn`; True once the worker said "done" (or its pipe is closed)."""
    try:
        while conn.poll():
            kind, a, rec, arr = conn.recv()
            if kind == "done":
                return True
            take(a, rec, arr)
    except (EOFError, OSError):
        return False
    return False
