"""Trained agents: the `sb3:` policies and the files they are read from.

`sb3` (`SB3Policy`: a Stable-Baselines3 agent behind the controllers' interface), `sb3_actor` (its actor in
numpy, row by row), `agent_interface` (the one observation and action layout agents see, shared with `train`),
`sb3_files` (a run folder read without running code it names), `untrusted` (pickles through an allow-list,
files and zips with size caps) and `untrusted_json` (the one reader of every JSON file mobman loads, which `eval`
and `train` use too).

May import: numpy, gymnasium, the standard library and modules of this package at the top; torch and
Stable-Baselines3 only inside functions (importing `policies` loads neither); `policies.base`, `policies.registry`
and `policies.knowledge` only inside functions (a residual agent's base controller).
"""
