"""Re-run the mutation check of issue 10: plant each known bug in a copy of the tree and run the tests that
must catch it.

    python tests/mutation/mutants.py              # every mutant, from the repository root
    python tests/mutation/mutants.py effort csv    # only the mutants whose name contains one of these words
    python tests/mutation/mutants.py --list        # the mutants and their tests
    python tests/mutation/mutants.py --baseline    # also run each mutant's tests on the unmutated copy

Each mutant is a text substitution in one source file (the original text must occur exactly once, so a
refactor that moves the code makes the mutant fail loudly as "stale" instead of silently testing nothing).
The tree is copied once (tracked and untracked files, not .git) to a temporary folder; each mutant is applied
there, its tests run with `python -m pytest -x -q` (PYTHONPATH = the copy), and the file is restored. A
mutant is "killed" when pytest exits with 1 (a test failed), "survived" when it exits with 0, "error" for any
other exit (collection error, crash). Exit status: 0 if every mutant was killed, 1 otherwise.

Not part of the test suite (pytest collects only test_*.py files). 12 mutants with --baseline: 3.5 min on the
shared 2-core machine (load ~10).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Mutant:
    name: str
    file: str
    old: str
    new: str
    tests: tuple[str, ...]
    note: str = ""


MUTANTS = (
    Mutant(
        "noise-arm-base-pos",
        "mobman_env/sensors.py",
        "            add(6, self.obs_noise, 2)\n",
        "",
        ("tests/test_mutants_env.py::test_sensor_noise_has_the_documented_std_on_each_noisy_key",),
    ),
    Mutant(
        "noise-arm-base-vel",
        "mobman_env/sensors.py",
        "            add(8, self.obs_noise_vel, 2)\n",
        "",
        ("tests/test_mutants_env.py::test_sensor_noise_has_the_documented_std_on_each_noisy_key",),
    ),
    Mutant(
        "kinematic-limit-hits-crossing",
        "mobman_env/sim.py",
        "                uu[i] = 0.0\n                hits += 1\n",
        "                uu[i] = 0.0\n",
        ("tests/test_mutants_env.py::test_kinematic_joint_limit_hits_are_counted_exactly",),
    ),
    Mutant(
        "kinematic-limit-hits-none",
        "mobman_env/sim.py",
        "        self._synced = False\n        return hits\n",
        "        self._synced = False\n        return 0\n",
        ("tests/test_mutants_env.py::test_kinematic_joint_limit_hits_are_counted_exactly",),
    ),
    Mutant(
        "effort-l1",
        "mobman_env/env.py",
        '"effort": -self.reward_weights["effort"] * float(a @ a)',
        '"effort": -self.reward_weights["effort"] * float(np.abs(a).sum())',
        ("tests/test_mutants_env.py::test_effort_term_is_the_squared_norm_of_the_clipped_action",),
    ),
    Mutant(
        "csv-x-y-swapped",
        "eval/output/results.py",
        '"axis_max_error_x_m": axis[0],\n                "axis_max_error_y_m": axis[1],',
        '"axis_max_error_x_m": axis[1],\n                "axis_max_error_y_m": axis[0],',
        (
            "tests/test_mutants_eval.py::test_csv_axis_columns_are_x_y_z_in_order",
            "tests/test_mutants_eval.py::test_results_csv_axis_columns_match_results_json",
        ),
    ),
    Mutant(
        "nnbc-plus-lookahead-removed",
        "policies/kernels/model_free.py",
        "        look = ipr[IPR_LOOKAHEAD] != 0 and not probing\n",
        "        look = False\n",
        ("tests/test_mutants_nnbc_plus.py",),
    ),
    Mutant(
        "nnbc-plus-lookahead-default-off",
        "policies/laws/nnbc_plus.py",
        "    lookahead: bool = True\n",
        "    lookahead: bool = False\n",
        ("tests/test_mutants_nnbc_plus.py",),
    ),
    Mutant(
        "train-atomic-write",
        "eval/output/files.py",
        '        with os.fdopen(fd, "wb") as f:\n',
        '        with open(path, "wb") as f:\n',
        ("tests/test_mutants_train.py::test_a_failing_checkpoint_write_keeps_the_previous_latest_json",),
    ),
    Mutant(
        "train-resume-seeding",
        "train/run.py",
        'model.set_random_seed(config.seed + ckpt["steps"])',
        "model.set_random_seed(config.seed)",
        ("tests/test_mutants_train.py::test_resume_seeds_the_training_envs_with_seed_plus_steps_done",),
    ),
    Mutant(
        "fig2b-sign",
        "eval/output/plots.py",
        'e = (np.asarray(rec["r_d"]) - np.asarray(rec["r_a"])) * 1e3',
        'e = (np.asarray(rec["r_a"]) - np.asarray(rec["r_d"])) * 1e3',
        ("tests/test_mutants_eval.py::test_axis_error_plot_shows_r_d_minus_r_a_in_mm",),
    ),
    Mutant(
        "one-frame-video",
        "eval/output/video.py",
        "            if k % stride == 0:\n",
        "            if k == 0:\n",
        ("tests/test_mutants_eval.py::test_video_holds_one_frame_per_frame_period_of_the_episode",),
    ),
)


def copy_tree(dest: Path) -> None:
    """Tracked and untracked (not ignored) files of the repository, as they are on disk."""
    out = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT,
        check=True,
        capture_output=True,
    ).stdout.decode()
    for rel in filter(None, out.split("\0")):
        src = ROOT / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)


def run_tests(tree: Path, tests: tuple[str, ...]) -> int:
    env = {**os.environ, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"}
    env["MOBMAN_NO_SKIPS"] = "0"  # a skip is an outcome here (counted as survived), not a session failure
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    return subprocess.run(cmd, cwd=tree, env=env, capture_output=True).returncode


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("words", nargs="*", help="run only the mutants whose name contains one of these")
    p.add_argument("--list", action="store_true", help="list the mutants and their tests, run nothing")
    p.add_argument("--baseline", action="store_true", help="also run each mutant's tests without the mutation")
    args = p.parse_args(argv)
    chosen = [m for m in MUTANTS if not args.words or any(w in m.name for w in args.words)]
    if args.list:
        for m in chosen:
            print(f"{m.name:34s} {m.file:24s} {' '.join(m.tests)}")
        return 0
    status = {}
    with tempfile.TemporaryDirectory(prefix="mobman-mutants-") as tmp:
        tree = Path(tmp)
        copy_tree(tree)
        for m in chosen:
            path = tree / m.file
            original = path.read_text()
            if original.count(m.old) != 1:
                status[m.name] = f"stale: the original text occurs {original.count(m.old)} times in {m.file}"
            else:
                base = ""
                if args.baseline:
                    rc0 = run_tests(tree, m.tests)
                    base = "baseline ok, " if rc0 == 0 else f"BASELINE FAILS (exit {rc0}), "
                path.write_text(original.replace(m.old, m.new))
                try:
                    rc = run_tests(tree, m.tests)
                finally:
                    path.write_text(original)
                outcome = {0: "survived", 1: "killed"}.get(rc, f"error (pytest exit {rc})")
                status[m.name] = base + outcome + (f" ({m.note})" if m.note and rc == 0 else "")
            print(f"{m.name:34s} {status[m.name]}", flush=True)
    killed = sum(s.endswith("killed") for s in status.values())
    print(f"{killed}/{len(status)} killed")
    return 0 if killed == len(status) else 1


if __name__ == "__main__":
    sys.exit(main())
