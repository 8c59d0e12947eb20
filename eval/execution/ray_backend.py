"""The Ray backend (`--backend ray [--address ADDRESS]`): every unit is one Ray task — a batch of kinematic
episodes sharing a vector env, or one episode (`eval.execution.batches.plan_units`, as the local backend cuts
them).

* **Same results as the local backend.** A task receives the run's config and its `Task`s (env id, dynamics,
  policy, seed, model error, noise), builds the env(s) and the policy inside the Ray worker process (its own
  PyBullet client), runs the rollout loop of `eval.rollout` (`rollout_batch` for a batch, with the
  same fallback to single episodes when a batch fails) and closes the envs, so no PyBullet client or
  temporary URDF outlives the task (Ray kills its worker processes without running their exit handlers).
  Every episode starts from `env.reset(seed)` and `policy.reset(..., seed=policy_seed(seed))`: the records equal those of
  `--backend local` except `wall_s`, `pid` and `predict_us_*` (tested on a local `ray.init(num_cpus=2)`).
* **Failures.** An exception inside an episode (policy or env) is a result, exactly as locally: the record gets
  `status: "failed"` and the traceback; it is not retried (same seed, same crash). A *task* that fails — its
  worker process dies (segfault, `os._exit`, out of memory, node lost) or it raises outside the episode (e.g.
  the policy objects cannot be unpickled because their module is missing on that node) — is run once more by
  Ray (`max_retries=1`, `retry_exceptions=True`); if the retry fails too, its episode(s) are recorded as failed
  with Ray's error (and the remote traceback), `pid` and `wall_s` null, and the other episodes finish.
* **Where Ray runs.** If this process already called `ray.init` (your script, a test fixture), that instance is
  used as it is and left running. Otherwise the run connects to `address` (`"auto"` on a node of a cluster
  started with `ray start --head`; `"HOST:6379"`; `"ray://HOST:10001"` for Ray Client) or, without an
  address, starts a local instance with `num_cpus = workers` (no dashboard, a 128 MiB object store, worker
  output not forwarded: tracebacks are in the records), and shuts it down at the end. That instance's
  servers listen on all network interfaces while it runs (Ray 2.60: its GCS, raylet and worker gRPC ports
  bind `*`, and `ray.init(_node_ip_address="127.0.0.1")` is rewritten to the node's address by Ray
  itself, so it cannot be confined to the loopback interface from here): on a machine reachable from an
  untrusted network, use `--backend local` or a firewall. Each task asks for one
  CPU; Ray sets `OMP_NUM_THREADS=1` in its workers.
* **Policy objects** given to `eval.run(config, policies={name: obj})` travel to the workers pickled (with
  Ray's cloudpickle, so classes defined in a script or a function work too); an object that cannot be pickled
  is refused before any rollout, naming it. Spec policies (`--policy nnbc`, `module:attr`, `sb3:PATH`) are
  built in the workers: on a cluster, mobman, the user's modules and model files must be available on every
  node (installed, or shipped with a Ray `runtime_env` given to your own `ray.init`).

Without Ray installed, `--backend ray` stops before any rollout saying `pip install "mobman[cluster]"`; an
`--address HOST:PORT` (or `ray://HOST:PORT`) that refuses a TCP connection, or does not take one within
`CONNECT_TIMEOUT_S` (10 s), is refused before any rollout too (Ray's own connection attempts retry for minutes).
"""

from __future__ import annotations

import contextlib
import logging
import os
import pickle
import re
import sys
from contextlib import contextmanager
from typing import Any

from eval.config import EvalConfig
from eval.errors import EvalError
from eval.execution.batches import UnitRunner, plan_units
from eval.execution.tasks import ExecutionInterrupted, Task, failed_record, keep_arrays

#: Ray re-runs a task once when its worker dies or it raises outside the episode; then it is recorded failed.
MAX_RETRIES = 1

#: Object store of a Ray instance started for a run: records and per-step arrays are small (0.3 MB for the
#: arrays of a 20 s episode), and Ray spills to disk beyond it.
OBJECT_STORE_BYTES = 128 * 2**20

#: How long the driver waits for finished tasks before it looks again (progress latency), s.
POLL_S = 0.2

INSTALL_HINT = 'pip install "mobman[cluster]"'

_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def require_ray():
    """Import and return `ray`, or raise `EvalError` saying how to install it."""
    try:
        import ray
    except ImportError as exc:
        raise EvalError(
            f"--backend ray needs Ray, which is not installed here ({exc}); install it with {INSTALL_HINT} "
            f'(or pip install "ray>=2.9"), or use --backend local'
        ) from None
    return ray


def serialize_policies(user: dict[str, Any]) -> bytes | None:
    """The user's policy objects pickled for the Ray workers (cloudpickle); EvalError if they cannot be."""
    if not user:
        return None
    from ray import cloudpickle

    try:
        return cloudpickle.dumps(user)
    except Exception as exc:
        bad = []
        for name, obj in user.items():
            try:
                cloudpickle.dumps(obj)
            except Exception:
                bad.append(f"{name!r} ({type(obj).__name__})")
        raise EvalError(
            f"policy object(s) {', '.join(bad) or sorted(user)} cannot be sent to Ray workers: with --backend ray "
            f"every policy object must be picklable ({type(exc).__name__}: {exc}). Drop what cannot be pickled "
            f"(open files, locks, threads, PyBullet clients) from the object or rebuild it in reset(); or make it "
            f"importable and pass it as --policy module:attr; or use --backend local"
        ) from None


def run_unit(
    config: EvalConfig, user_bytes: bytes | None, unit: list[Task], keep: list[bool]
) -> list[tuple[dict, dict | None]]:
    """Body of one Ray task, in a Ray worker process: build the env(s) and policy, run the unit's episodes (a
    batch, or one episode: `eval.execution.batches`), close; one (record, arrays or None) per task of `unit`."""
    user = pickle.loads(user_bytes) if user_bytes else {}
    runner = UnitRunner(config, user)
    try:
        done = {task.index: (rec, arrays) for task, rec, arrays in runner.run(unit)}
    finally:
        runner.close()
    return [(done[t.index][0], done[t.index][1] if k else None) for t, k in zip(unit, keep)]


_REMOTE = None


def _remote_task():
    global _REMOTE
    if _REMOTE is None:
        ray = require_ray()
        _REMOTE = ray.remote(num_cpus=1, max_retries=MAX_RETRIES, retry_exceptions=True)(run_unit)
    return _REMOTE


def local_runtime_env() -> dict[str, Any]:
    """A Ray `runtime_env` giving local Ray workers this process's own import directories.

    Ray gives its workers only the driver's script directory and working directory; spawned local worker
    processes get the parent's whole `sys.path`. So that `--policy module:attr` and pickled policy objects
    import in Ray workers exactly as in local ones, the entries of `sys.path` outside the Python installation
    (a project or tests directory, a PYTHONPATH) are put on the workers' PYTHONPATH."""
    prefixes = {os.path.realpath(p) for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)}
    extra = []
    for entry in sys.path:
        path = os.path.realpath(entry or os.curdir)
        if (
            os.path.isdir(path)
            and not any(path == p or path.startswith(p + os.sep) for p in prefixes)
            and path not in extra
        ):
            extra.append(path)
    if os.environ.get("PYTHONPATH"):
        extra.append(os.environ["PYTHONPATH"])
    return {"env_vars": {"PYTHONPATH": os.pathsep.join(extra)}} if extra else {}


#: How long a run waits for the TCP connection to a `--address HOST:PORT` before it gives up, s (a refused
#: port fails at once; Ray itself would retry for minutes).
CONNECT_TIMEOUT_S = 10.0


def check_address(address: str | None, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Raise `EvalError` within `timeout` s if `address` ("HOST:PORT" or "ray://HOST:PORT") takes no TCP
    connection. "auto" and None are left to Ray (it reads the address of the cluster on this node)."""
    if address is None or address == "auto":
        return
    text = address[len("ray://") :] if address.startswith("ray://") else address
    host, sep, port_text = text.rpartition(":")
    if not sep or not port_text.isdigit() or not host:
        raise EvalError(
            f"--address {address!r} is not HOST:PORT, ray://HOST:PORT or auto; e.g. --address 10.0.0.5:6379"
        )
    import socket

    try:
        with socket.create_connection((host.strip("[]"), int(port_text)), timeout=timeout):
            pass
    except OSError as exc:
        reason = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise EvalError(
            f"cannot reach the Ray cluster at --address {address!r} ({reason} within {timeout:g} s). Start it "
            f"with `ray start --head` on the head node, check the host and port (the head prints them), or use "
            f"--address auto on a node of the cluster, or drop --address for a local Ray instance"
        ) from None


def init_kwargs(config: EvalConfig) -> dict[str, Any]:
    """Arguments of `ray.init` for a run that starts (no address) or joins (address) Ray itself."""
    common = {"log_to_driver": False, "logging_level": logging.ERROR}
    if config.address is not None:
        return {"address": config.address, **common}
    # address="local": a new instance even when a cluster runs on this machine (plain ray.init() would join it)
    return {
        "address": "local",
        "num_cpus": config.workers,
        "include_dashboard": False,
        "object_store_memory": OBJECT_STORE_BYTES,
        "runtime_env": local_runtime_env(),
        **common,
    }


@contextmanager
def ray_session(config: EvalConfig):
    """Use the Ray instance this process already initialised, or start / join one and shut it down after."""
    ray = require_ray()
    if ray.is_initialized():
        yield ray
        return
    try:
        ray.init(**init_kwargs(config))
    except Exception as exc:
        where = f"the Ray cluster at --address {config.address!r}" if config.address else "a local Ray instance"
        raise EvalError(
            f"cannot start or reach {where}: {type(exc).__name__}: {str(exc).rstrip('.')}. For a cluster, run "
            f"`ray start --head` on "
            f"the head node (and `ray start --address HEAD:6379` on the others), then pass --address auto on a "
            f"node of it, or --address HEAD:6379"
        ) from None
    try:
        yield ray
    finally:
        ray.shutdown()


def task_error_text(exc: BaseException) -> str:
    """Ray's error (with the remote traceback when there is one), without terminal colour codes."""
    text = _ANSI.sub("", str(exc)).strip()
    msg = f"the Ray task failed and its retry failed too ({MAX_RETRIES} retry): {type(exc).__name__}: {text}"
    if "ModuleNotFoundError" in text:
        msg += (
            "\n(the Ray worker cannot import a module the policy objects need: install it on every node, or "
            "ship it with a runtime_env (working_dir / py_modules) given to your own ray.init before eval.run)"
        )
    return msg


def execute_ray(
    config: EvalConfig, user: dict, tasks: list[Task], on_result=None
) -> tuple[dict[int, dict], dict[int, dict]]:
    """Run `tasks` as Ray tasks; returns ({index: record}, {index: arrays}) like `eval.execution.local.execute_local`.

    `on_result(record)` is called in this process as each episode ends (in completion order)."""
    require_ray()
    user_bytes = serialize_policies(user)  # refused here, before Ray starts, if it cannot be pickled
    records: dict[int, dict] = {}
    arrays: dict[int, dict] = {}
    if not tasks:
        return records, arrays
    try:
        _run_on_ray(config, user_bytes, user, tasks, records, arrays, on_result)
    except KeyboardInterrupt:  # the pending tasks are cancelled and the instance started for the run shut down
        raise ExecutionInterrupted(records, arrays) from None
    return records, arrays


def _run_on_ray(
    config: EvalConfig, user_bytes, user: dict, tasks: list[Task], records: dict, arrays: dict, on_result
) -> None:
    with ray_session(config) as ray:
        remote = _remote_task()
        cfg_ref = ray.put(config)
        user_ref = ray.put(user_bytes)
        units = plan_units(config, user, tasks)
        pending = {
            remote.remote(cfg_ref, user_ref, unit, [keep_arrays(config, t) for t in unit]): unit for unit in units
        }
        try:
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=len(pending), timeout=POLL_S)
                for ref in ready:
                    unit = pending.pop(ref)
                    try:
                        results = ray.get(ref)
                    except Exception as exc:  # the task and its retry failed (RayTaskError, WorkerCrashedError, ...)
                        results = [(failed_record(task, task_error_text(exc)), None) for task in unit]
                    for task, (rec, arr) in zip(unit, results):
                        if on_result is not None:  # first: a record whose journaling was interrupted is dropped
                            on_result(rec)
                        records[task.index] = rec
                        if arr is not None:
                            arrays[task.index] = arr
        finally:
            for ref in pending:  # interrupted (Ctrl-C): leave no task running on a shared cluster
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=True)
