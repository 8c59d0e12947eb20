"""Compiling the controllers' numba kernels ahead of use: `warm()` calls each with the argument types the package
passes (numba keeps the machine code in its cache), and `KERNEL_MODULES` are the modules holding them, for
`mobman_env.kernel_cache.cold_kernels` (will a call compile?). `python -m policies` and `mobman-eval`'s commands
(`eval.execution.warmup`) run it, so that no episode pays the first compile.
"""

import time

import numpy as np

from mobman_env.params import RobotParams
from policies.base import EnvFacts
from policies.kernels import model_free, mpc_model, shared
from policies.kernels.shared import damped_pinv_apply_rows
from policies.laws import calib_qp, nnbc
from policies.laws.broyden_rls import RLS, Broyden
from policies.laws.estimators import BroydenEstimator
from policies.laws.mpc import MPC, MPCConfig
from policies.laws.nnbc_plus import NNBCPlus, NNBCPlusConfig

#: every module of `policies` with `@njit(cache=True)` kernels (a test checks the list is complete)
KERNEL_MODULES = (shared, nnbc, calib_qp, model_free, mpc_model)


def warm() -> float:
    """Compile (or load from numba's cache) every controller kernel for the argument types the package passes;
    returns the seconds it took."""
    t0 = time.perf_counter()
    J, v = np.ones((1, 3, 8)), np.ones((1, 3))
    damped_pinv_apply_rows(J, v, 0.02, 0.02)
    rows = np.arange(1)
    nnbc._znn_rows(J, np.zeros((1, 3)), v, np.ones((1, 8)), rows, 0.9, 1e-3)
    nnbc._residual_rows(J, v, np.ones((1, 8)), rows, np.empty((1, 3)))
    three, two, ints = np.ones((1, 3)), np.ones((1, 2)), np.zeros(1, dtype=np.intp)
    obs = (three, two, two, np.ones(1), np.ones((1, 8)), 0.01)
    est = (np.zeros((1, 13)), np.zeros((1, 13, 13)), np.zeros((1, 13)), three, three, three, np.zeros((1, 6)))
    calib_qp.calibrate_rows(
        three, ints, ints, ints, *obs, *est, 1.0, 1.0, 1.0, 0.0, np.zeros((1, 8, 8)), np.ones((1, 64))
    )
    # the model-free law (policies.kernels.model_free): each estimator kind through the probe into the estimate
    facts = EnvFacts(dt=0.01, action_scale=(3.0,) * 6 + (10.0, 10.0), obs_keys=())
    sizes = {"ee_pos": 3, "ee_vel": 3, "arm_base_pos": 2, "arm_base_vel": 2, "joint_pos": 8, "joint_vel": 8}
    single = {k: np.full(m, 0.01) for k, m in {**sizes, "target_pos": 3, "target_vel": 3, "base_yaw": 1}.items()}
    for policy in (
        NNBCPlus(facts),
        NNBCPlus(facts, NNBCPlusConfig(formulation="whole_body")),
        Broyden(facts),
        RLS(facts),
    ):
        policy.reset(single, seed=0)
        for _ in range(2 * 8 + 2):
            policy.predict(single)
    BroydenEstimator(8, step=1.0, min_speed=0.01).update(np.ones(8), np.ones(3))
    # mpc: one row and two (numba types a column of one row as contiguous, of two as strided), with a path
    nominal = RobotParams.nominal()
    task = {"task": {"path": {"type": "circle", "duration": 2.0}, "start": [0.0, 0.0, 1.0]}}
    one = {**single, "time": np.zeros(1)}
    mpc = MPC(facts, nominal_params=nominal)
    mpc.reset(one, task)
    for _ in range(2):  # the second step fits the lag (`mpc_model.lag_fit_rows`)
        mpc.predict(one)
    law = MPC.batched(facts, MPCConfig(), 2, None, nominal_params=lambda i: nominal)
    law.reset({k: np.stack([v, v]) for k, v in one.items()})
    for _ in range(2):
        law.predict({k: np.stack([v, v]) for k, v in one.items()})
    return time.perf_counter() - t0
