"""`python -m policies`: compile the controllers' numba kernels once (numba keeps their machine code in its cache),
so that no later process pays the first compile; as `python -m mobman_env` does for the engine."""

from policies.warm import warm

print(f"policies: controller kernels ready in {warm():.1f} s")
