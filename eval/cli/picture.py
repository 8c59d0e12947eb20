"""`mobman-eval picture`: the README's picture, one rendered frame of the robot tracking a path (parses into
`PictureConfig`, calls `eval.output.picture.render_picture`, which writes the PNG and a JSON record beside it;
with `--gallery DIR`, `render_gallery`: the robots, one PNG each; with `--traces PNG`, `render_traces`: the
tracking error of one controller per family)."""

from __future__ import annotations

from pathlib import Path

from eval.cli.options import Opt, add_options, build
from eval.config import DYNAMICS_CHOICES
from eval.execution.warmup import warm_kernels
from eval.output import picture
from eval.output.picture import PictureConfig, render_gallery, render_picture, render_traces

OPTIONS = (
    Opt("out", metavar="PNG"),
    Opt("gallery", metavar="DIR"),
    Opt("traces", metavar="PNG"),
    Opt("env", metavar="ID"),
    Opt("policy", metavar="SPEC"),
    Opt("seed", metavar="S"),
    Opt("dynamics", choices=DYNAMICS_CHOICES, metavar="MODE"),
    Opt("width", metavar="PX"),
    Opt("height", metavar="PX"),
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "picture",
        help="render one episode's last frame with the path and the traces drawn in (the README's picture)",
        description=(picture.__doc__ or "").split("\n\n")[0],
    )
    add_options(p, PictureConfig, OPTIONS)


def main(args) -> int:
    config = build(PictureConfig, args, OPTIONS)
    config.validate()
    warm_kernels()  # a cold numba cache compiles here, said: the episode would otherwise sit silent for ~30 s
    if config.gallery is not None:
        record = render_gallery(config)
        print(f"{config.gallery}: {', '.join(f'{stem}.png' for stem in record['robots'])} and gallery.json")
        return 0
    if config.traces is not None:
        record = render_traces(config)
        worst = ", ".join(f"{spec} {ep['max_error_mm']} mm" for spec, ep in record["episodes"].items())
        print(f"{config.traces} and {Path(config.traces).with_suffix('.json')}: max error {worst}")
        return 0
    record = render_picture(config)
    print(
        f"{config.out} and its record {Path(config.out).with_suffix('.json')}: {config.policy} on {config.env} "
        f"({config.dynamics}), RMS error {record['rms_error_mm']} mm"
    )
    return 0
