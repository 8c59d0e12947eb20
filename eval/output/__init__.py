"""eval.output: everything eval writes — files (atomic writes, the output folder), provenance, results.json /
results.csv (`results`), Markdown and console tables (`tables`), plots and videos.

May import: `eval.errors`, `eval.config`, `eval.metrics`, `eval.rollout` (video only), `mobman_env`; never
`eval.execution`, `eval.sweep`, `eval.cli` or the runners.
"""
