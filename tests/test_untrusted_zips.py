"""Zip bombs nested in a model.zip: torch saves `policy.pth` as a zip inside the zip, and `torch.load` inflates
each record to the size the inner archive declares. The cap counts those records, read from the inner central
directory before any record is inflated (`policies.agents.untrusted.check_nested_zip_sizes`)."""

from __future__ import annotations

import io
import shutil
import struct
import zipfile

import pytest

import policies
from policies.agents.sb3_files import read_zip_data
from policies.agents.untrusted import MAX_MODEL_ZIP_BYTES, FileRefused

pytest.importorskip("stable_baselines3")

BIG = 2 * 2**30  # the 2 GiB record of the report


def _declare(archive: bytes, size: int) -> bytes:
    """`archive` (a zip) with the uncompressed size its central directory declares for its records set to
    `size`: a small file whose records claim to inflate to gigabytes, built without inflating anything."""
    out = bytearray(archive)
    start = out.find(b"PK\x01\x02")
    while start >= 0:
        out[start + 24 : start + 28] = struct.pack("<I", size)
        start = out.find(b"PK\x01\x02", start + 4)
    return bytes(out)


def _bomb_model(tmp_path, compression=zipfile.ZIP_STORED):
    """The shipped SAC's folder, its model.zip's `policy.pth` replaced by an inner archive whose record declares
    2 GiB (as the report's 3.6 MB file did)."""
    src = policies.agents.sb3.MODELS_DIR / "sac-circle"
    d = shutil.copytree(src, tmp_path / "bomb")
    inner = io.BytesIO()
    with zipfile.ZipFile(inner, "w") as zf:
        zf.writestr("archive/data/0", b"\0" * 4096)
    with zipfile.ZipFile(src / "model.zip") as zf:
        entries = {n: zf.read(n) for n in zf.namelist()}
    entries["policy.pth"] = _declare(inner.getvalue(), BIG)
    with zipfile.ZipFile(d / "model.zip", "w", compression=compression) as zf:
        for name, raw in entries.items():
            zf.writestr(name, raw)
    return d


@pytest.mark.parametrize("compression", [zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED], ids=["stored", "deflated"])
def test_a_record_inside_policy_pth_beyond_the_cap_is_refused_uninflated(tmp_path, monkeypatch, compression):
    d = _bomb_model(tmp_path, compression)
    opened: list[str] = []
    real_open = zipfile.ZipFile.open

    def watching(self, name, *args, **kwargs):
        opened.append(name if isinstance(name, str) else name.filename)
        return real_open(self, name, *args, **kwargs)

    monkeypatch.setattr(zipfile.ZipFile, "open", watching)
    with pytest.raises(
        FileRefused, match=rf"entry 'policy.pth' is an archive whose records inflate to {BIG} bytes"
    ) as info:
        read_zip_data(d / "model.zip")
    assert f"at most {MAX_MODEL_ZIP_BYTES} are read: copy the file again" in str(info.value)
    assert "archive/data/0" not in opened, opened  # the inner record was never opened, let alone inflated


def test_an_entry_that_starts_like_a_zip_but_is_not_one_is_refused(tmp_path):
    d = _bomb_model(tmp_path)
    with zipfile.ZipFile(d / "model.zip") as zf:
        entries = {n: zf.read(n) for n in zf.namelist()}
    entries["policy.pth"] = b"PK\x03\x04" + b"\0" * 64
    with zipfile.ZipFile(d / "model.zip", "w") as zf:
        for name, raw in entries.items():
            zf.writestr(name, raw)
    with pytest.raises(FileRefused, match=r"entry 'policy.pth' starts like a zip archive but is not one"):
        read_zip_data(d / "model.zip")


def test_the_shipped_agents_pass_the_nested_cap():
    for name in ("sac-circle", "ppo-circle", "ppo-circle-physics"):
        assert "policy_class" in read_zip_data(policies.agents.sb3.MODELS_DIR / name / "model.zip")


def test_mobman_eval_run_refuses_the_nested_bomb_with_exit_2(tmp_path, capsys):
    from eval.cli import main

    d = _bomb_model(tmp_path)
    out = tmp_path / "o"
    assert main(["run", "--policy", f"sb3:{d}", "--seeds", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "entry 'policy.pth' is an archive whose records inflate to" in err and "copy the file again" in err
    assert "Traceback" not in err and not out.exists()
