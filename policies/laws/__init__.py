"""The built-in controllers: one module per family, each with its config dataclasses, its controller classes and
their vectorised law (`batched`), named by `policies.registry` and built by `policies.make`.

`simple` (`zero`, `random`), `jmpi` (`jmpi`, `clik`, `oracle`), `nnbc` (the paper's NNBC), `qp` (`qp`,
`qp-oracle`), `calib_qp` (`calib-qp`), `mpc` (`mpc`, `mpc-oracle`), `nnbc_plus` (`nnbc-plus`, `nnbc-plus-wb`) with
its Jacobian estimators `estimators` and `structured`, and `broyden_rls` (`broyden`, `rls`).

May import: `mobman_env`, `policies.base`, `policies.batched`, `policies.kernels` and modules of this package (a
law built on another one's: `qp` on `jmpi`'s gain, `calib_qp` and `mpc` on `qp`, `broyden_rls` on `nnbc_plus`);
never `policies.registry`, `policies.agents` or `eval`.
"""
