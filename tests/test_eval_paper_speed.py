"""`mobman-eval paper` and `mobman-eval speed` end to end, at their smallest sizes (kinematic, one seed)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from eval import paper
from eval.cli import main
from eval.output.precision import format_mm

#: reported seed of this module (the paper command starts at 10,000 by design)
PAPER_SEEDS = 1


def test_paper_writes_figures_and_sets_claims_beside_measurements(tmp_path):
    out = tmp_path / "paper"
    rc = main(
        [
            "paper",
            "--out",
            str(out),
            "--seeds",
            str(PAPER_SEEDS),
            "--dynamics",
            "kinematic",
            "--workers",
            "1",
            "--quiet",
        ]
    )
    assert rc == 0
    for name in (
        "paper.md",
        "results.json",
        "summary.md",
        "fig2a_kinematic.png",
        "fig2b_kinematic.png",
        "fig3_kinematic.png",
    ):
        assert (out / name).is_file(), name
    res = json.loads((out / "results.json").read_text())
    policies = [a["policy"] for a in res["aggregate"]]
    assert policies[:4] == ["nnbc", "jmpi", "oracle:gamma=10", "nnbc-full"]
    assert {r["seed"] for r in res["episodes"]} == {10_000}
    assert {r["env"] for r in res["episodes"]} == {"WheeledPuma-Circle-v0"}
    md = (out / "paper.md").read_text()
    # the path's size is measured from r_d, and the formula's is computed from the spec: both 0.80 x 0.69 x 0.40
    assert "0.80 x 0.69 x 0.40 m (extent of r_d)" in md
    assert "0.8 x 0.8 x 0.2 m" in md
    nnbc = next(r for r in res["episodes"] if r["policy"] == "nnbc")
    # the measured number, not a constant, with the digits a chaotic controller's result has
    assert f"{format_mm(nnbc['max_error_m'], 'nnbc', 1)} mm" in md
    assert "## Baselines the paper did not run" in md
    for claim in (
        "NNBC max error <= 6 mm (kinematic)",
        "JMPI fails (kinematic)",
        "NNBC better than JMPI (kinematic)",
        "## Where we differ, and why",
    ):
        assert claim in md


def test_path_extent_and_formula():
    spec = {"type": "circle", "radius": 0.4, "tilt": math.pi / 6}
    np.testing.assert_allclose(paper.formula_extent(spec), [0.8, 0.8 * math.cos(math.pi / 6), 0.4])
    s = np.linspace(0, 2 * math.pi, 2001)
    r_d = np.c_[0.4 * np.cos(s) - 0.4, 0.4 * math.cos(math.pi / 6) * np.sin(s), 0.4 * math.sin(math.pi / 6) * np.sin(s)]
    np.testing.assert_allclose(paper.path_extent(r_d), paper.formula_extent(spec), atol=1e-6)


def test_paper_rejects_bad_seeds(tmp_path, capsys):
    assert main(["paper", "--out", str(tmp_path / "p"), "--seeds", "0", "--quiet"]) == 2
    assert "--seeds must be an integer >= 1" in capsys.readouterr().err


def test_speed_writes_speed_json(tmp_path):
    out = tmp_path / "speed"
    rc = main(
        [
            "speed",
            "--steps",
            "40",
            "--repeats",
            "1",
            "--episodes",
            "2",
            "--batch-size",
            "2",
            "--policy",
            "zero",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert rc == 0
    res = json.loads((out / "speed.json").read_text())
    blocks = {(b["dynamics"], b["n_substeps"]) for b in res["env"]}
    assert blocks == {("kinematic", 2), ("physics", 2), ("physics", 4), ("physics", 10)}
    for b in res["env"]:
        # best of --repeats (1 here) timings of --steps (40) steps each, env and bare on the same figures
        assert b["steps"] == 40 and len(b["env_steps_per_s_all"]) == len(b["bare_steps_per_s_all"]) == 1
        assert b["env_steps_per_s"] == max(b["env_steps_per_s_all"])
        assert b["bare_steps_per_s"] == max(b["bare_steps_per_s_all"])
    pred = {r["policy"]: r for r in res["predict"]}
    assert pred["zero"]["status"] == "ok" and pred["zero"]["calls"] == 2000
    assert pred["zero"]["predict_us_p99"] >= pred["zero"]["predict_us_median"] > 0
    # eval.run one episode at a time, then batched (2 episodes, 2 workers: a batch of one each)
    assert [(e["workers"], e["batch_size"], e["processes"]) for e in res["episodes"]] == [
        (1, 1, 1),
        (2, 1, 2),
        (1, 64, 1),
        (2, 64, 2),
    ]
    assert [v["num_envs"] for v in res["vector"]] == [1, 64, 1024]
    assert all(v["robot_steps_per_s"] == max(v["robot_steps_per_s_all"]) for v in res["vector"])
    assert [(r["policy"], r["status"]) for r in res["batched_predict"]] == [("zero", "ok")]
    assert [(e["policy"], e["episodes"], e["status"]) for e in res["batch_episodes"]] == [
        ("nnbc", 2, "ok"),
        ("clik", 2, "ok"),
    ]
    text = (out / "speed.md").read_text()
    assert "## Figures" in text and "vector env, N = 1,024" in text and "peers" not in res


def test_speed_times_the_kinematic_half_of_paper_on_request(tmp_path, monkeypatch):
    """`--paper` runs `eval.paper.reproduce(dynamics="kinematic", workers=1)` in the process and reports its CPU
    seconds, episodes and controllers (the reproduction itself is faked here: `test_paper_*` run it)."""
    import eval.paper
    import eval.speed as S

    calls = []

    def fake_reproduce(out, dynamics, workers, overwrite, progress):
        calls.append((dynamics, workers))
        episodes = [{"policy": p, "status": "ok"} for p in ("nnbc", "jmpi") for _ in range(3)]
        Path(out, "results.json").write_text(json.dumps({"episodes": episodes}))
        return Path(out)

    monkeypatch.setattr(eval.paper, "reproduce", fake_reproduce)
    res = S.paper_kinematic_seconds()
    assert calls == [("kinematic", 1)]
    assert res["episodes"] == 6 and res["failed"] == 0 and res["policies"] == ["jmpi", "nnbc"] and res["cpu_s"] >= 0
    row = S.markdown({**_minimal_speed_result(), "paper": res}).splitlines()[-1]
    assert row.startswith("| `mobman-eval paper --dynamics kinematic --workers 1` (6 episodes, 2 controllers")


def _minimal_speed_result() -> dict:
    block = {"dynamics": "kinematic", "n_substeps": 2, "env_steps_per_s": 1000.0}
    physics = [
        {
            "dynamics": "physics",
            "n_substeps": n,
            "env_steps_per_s": 1.0,
            "bare_steps_per_s": 1.0,
            "ratio_env_to_bare": 1,
        }
        for n in (2, 4, 10)
    ]
    return {
        "machine": {"cpus": 2, "platform": "test", "loadavg_1_5_15_at_start": None},
        "settings": {"repeats": 1, "steps": 1},
        "when": "now",
        "env": [block, *physics],
        "predict": [],
        "episodes": [],
    }


def test_speed_refuses_an_unknown_policy_before_measuring(tmp_path, capsys, monkeypatch):
    import functools

    from eval import speed

    fail = functools.wraps(speed.measure)(lambda *a, **k: pytest.fail("the benchmark ran"))
    monkeypatch.setattr(speed, "measure", fail)
    out = tmp_path / "speed"
    assert main(["speed", "--policy", "zero", "--policy", "bogus", "--out", str(out), "--quiet"]) == 2
    assert "policy 'bogus': unknown policy 'bogus'" in capsys.readouterr().err
    assert not out.exists()


def test_speed_refuses_existing_out(tmp_path, capsys):
    out = tmp_path / "taken"
    out.mkdir()
    (out / "x").write_text("x")
    assert main(["speed", "--out", str(out), "--steps", "10"]) == 2
    assert "--overwrite" in capsys.readouterr().err


def _fake_result(errors: dict[str, list[float]], dyn: str = "kinematic"):
    """A RunResult with hand-made max errors per policy (m), for the claim logic of paper.md."""
    from eval.metrics import aggregate
    from eval.runner import RunResult

    recs = []
    for policy, errs in errors.items():
        for k, e in enumerate(errs):
            recs.append(
                {
                    "env": paper.PAPER_ENV,
                    "policy": policy,
                    "dynamics": dyn,
                    "model_error": 0.05,
                    "obs_noise": 0.0,
                    "episode": k,
                    "seed": 10_000 + k,
                    "status": "ok",
                    "max_error_m": e,
                    "success": e <= 0.006,
                    "tipped_over": False,
                    "index": len(recs),
                    "path": {"type": "circle", "radius": 0.4, "tilt": math.pi / 6},
                }
            )
    results = {
        "config": {"dynamics": [dyn], "episodes": len(next(iter(errors.values()))), "seed": 10_000, "workers": 1},
        "git": "x",
        "episodes": recs,
        "aggregate": aggregate(recs),
    }
    s = np.linspace(0, 2 * math.pi, 200)
    r_d = np.c_[0.4 * np.cos(s) - 0.4, 0.4 * math.cos(math.pi / 6) * np.sin(s), 0.2 * np.sin(s)]
    return RunResult(out=None, results=results, arrays={0: {"r_d": r_d}})


@pytest.mark.parametrize(
    "nnbc, jmpi, expect",
    [
        (
            [0.002, 0.004, 0.005],
            [0.05, 0.08, 0.04],
            [
                "<= 6 mm in 3/3 seeds | holds",
                "> 6 mm in 3/3 seeds",
                "NNBC ~4 mm vs JMPI 50.0 mm | holds",  # nnbc is chaotic: one significant digit
                "within 6 mm in every seed (median ~4 mm), as the paper says",
            ],
        ),
        (
            [0.02, 0.03, 0.09],
            [0.05, 0.004, 0.003],
            [
                "<= 6 mm in 0/3 seeds | does not hold",
                "> 6 mm in 1/3 seeds, 0.13 x NNBC's median | does not hold",
                "NNBC ~30 mm vs JMPI 4.0 mm | does not hold",
                "within 6 mm in 2/3 seeds",
            ],
        ),
    ],
)
def test_paper_claims_follow_the_measurements(nnbc, jmpi, expect):
    result = _fake_result({"nnbc": nnbc, "jmpi": jmpi, "oracle": [0.001, 0.001, 0.001]})
    md = paper.paper_markdown(result, ("nnbc", "jmpi", "oracle"), [], {}, 1.0)
    for needle in expect:
        assert needle in md, (needle, md)


def test_paper_keeps_the_papers_gains_and_takes_the_new_baselines_when_registered():
    from policies.laws.jmpi import OracleConfig
    from policies.laws.nnbc import NNBCConfig
    from policies.registry import KNOWN_POLICIES

    specs, notes = paper.choose_policies("kinematic")
    assert paper.spec_of(specs, "oracle") == "oracle:gamma=10"  # explicit: the law's default gain is 20
    assert OracleConfig().gamma != paper.PAPER_GAMMA
    assert (paper.spec_of(specs, "nnbc") == "nnbc") is (NNBCConfig().gamma == NNBCConfig().mu == paper.PAPER_GAMMA)
    for name in ("clik", "qp-oracle"):
        assert (name in specs) is (name in KNOWN_POLICIES)
        assert any(f"`{name}` is not registered" in n for n in notes) is (name not in KNOWN_POLICIES)


def test_paper_says_what_clik_and_the_ceiling_mean():
    absent = paper.paper_markdown(_fake_result({"nnbc": [0.02] * 3, "jmpi": [0.05] * 3}), ("nnbc", "jmpi"), [], {}, 1)
    assert "**`clik` was not run**" in absent and "**`qp-oracle` was not run**" in absent
    result = _fake_result(
        {
            "nnbc": [0.02, 0.03, 0.004],
            "jmpi": [0.05, 0.08, 0.04],
            "clik": [0.001, 0.002, 0.001],
            "oracle": [0.01, 0.02, 0.001],
            "qp-oracle": [0.0001, 0.0002, 0.0001],
        }
    )
    md = paper.paper_markdown(result, ("nnbc", "jmpi", "oracle", "clik", "qp-oracle"), [], {}, 1.0)
    assert "within 6 mm in 3/3 seeds (median 1.0 mm); JMPI in 0/3, `nnbc` in 1/3" in md
    assert "JMPI's failure is the failure of open loop" in md
    assert "holds against JMPI only" in md
    assert "`qp-oracle`, kinematic:** within 6 mm in 3/3 seeds, median max error 0.10 mm" in md
    assert "(eq. (10) with the same knowledge, `oracle`: 1/3)" in md
    assert "`nnbc`'s median is ~200 times it" in md
    assert "| clik (kinematic) |" in md.replace("| nnbc (kinematic) | jmpi (kinematic) ", "| ")


def test_speed_peers_are_raced_interleaved_with_ratios():
    pytest.importorskip("panda_gym")
    pytest.importorskip("mujoco")
    from eval import speed

    rows = speed.peer_steps(steps=5, repeats=2)
    assert [(r["id"], r["status"]) for r in rows] == [("PandaReach-v3", "ok"), ("Reacher-v5", "ok")]
    for r in rows:
        ratio = r["mobman_kinematic_steps_per_s"] / r["peer_steps_per_s"]
        assert r["ratio_mobman_to_peer"] == pytest.approx(ratio)
