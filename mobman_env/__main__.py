"""`python -m mobman_env`: compile the engine's kernels once (numba keeps them in its cache; see
`mobman_env.engine.warm`), so that no later process pays the first compile."""

from mobman_env import feasibility
from mobman_env.engine import warm

print(f"mobman_env: engine kernels ready in {warm() + feasibility.warm():.1f} s")
