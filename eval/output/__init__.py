"""eval.output: everything eval writes — files (atomic writes, the output folder), provenance, results.json /
results.csv (`results`), Markdown and console tables (`tables`), plots (one colour per controller, a line
style per knowledge class: `styles`) and videos, the episode journal (`journal`), the generated blocks of Markdown
pages (`readme`: from results files; `layout`: from the source tree; `blocks`: finding them in one pass and
escaping what is copied into them).

May import: `eval.errors`, `eval.config`, `eval.metrics`, `eval.rollout` (video only), `mobman_env`,
`policies.knowledge` (`styles`), `policies.agents.untrusted` (`readme`: reading pages and sources); never
`eval.execution`, `eval.sweep`, `eval.cli` or the runners.
"""
