"""The controllers' numba kernels: scalar per-row code compiled with `@njit(cache=True)` and looped over N rows
(STYLE 17), the single controller being the N = 1 case.

`shared` (the damped pseudo-inverse and a model's Jacobian, for `nnbc`, `jmpi`, `clik`, the oracle, `qp` and
`mpc`), `model_free` (the law of `nnbc-plus`, `broyden` and `rls`) and `mpc_model` (`mpc`'s prediction model).
`policies.warm` compiles them all, with the kernels `policies.laws.nnbc` and `policies.laws.calib_qp` hold.

May import: numpy, numba, the standard library, `mobman_env` and `policies.base`; never `policies.laws`,
`policies.agents` or `policies.registry`.
"""
