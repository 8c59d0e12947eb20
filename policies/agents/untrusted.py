"""Reading files that may be crafted: pickles through an allow-list, regular files and zip entries with size caps.

**Pickles.** `pickle.load` calls whatever a pickle names, so every file of an SB3 agent or a mobman-train
checkpoint is read with `RestrictedUnpickler`, whose `find_class` resolves a name only if the pair
(module, name) is one of an allow-list of exact pairs (the `ALLOWED_*` sets below, spelled out, no prefixes):

* a name with a dot is refused before anything is imported: at protocol >= 4 `pickle.Unpickler.find_class`
  resolves `a.b.c` attribute by attribute, which reaches any module's `__builtins__`
  (`numpy.random.__builtins__.get` -> `eval`);
* a pair outside the list is refused (`builtins.eval`, `os.system`, `operator.attrgetter`,
  `functools.partial`, `builtins.getattr`, ...), whatever the protocol (2 to 5) and opcode (GLOBAL,
  STACK_GLOBAL); Python 2 names (`__builtin__.set`) are mapped to Python 3's first, as pickle does, and then
  checked;
* an allowed pair is resolved as `getattr(import_module(module), name)`, never through pickle's own lookup.

Each refusal raises `UnsafePickleError` naming the module and name. The lists hold only what the files of
Stable-Baselines3 2.x and mobman-train contain: numpy arrays, scalars and dtypes, the bit generators and seed
sequences of a space's random state, plain containers, gymnasium spaces, SB3 policy and feature-extractor
classes, torch activation and optimiser classes (`ALLOWED_MODEL`), and for training checkpoints also SB3's
schedules, buffers, train frequency, action noise, `VecNormalize`, `RunningMeanStd` and `torch.device`
(`ALLOWED_CHECKPOINT`). Tested with a family of crafted pickles (tests/test_untrusted_pickles.py).

**Sizes.** `read_regular` reads a file only if it is a regular file (not a FIFO, a device such as `/dev/zero`
or a directory; a symlink counts as what it points to) of at most a given size; `check_zip_sizes` refuses a
zip whose entries declare more than the caps decompressed (zipfile never yields more than an entry declares).

This narrows what a file can do; it is not a sandbox: load only agents you trust.
May import the standard library only (numpy, gymnasium, torch and SB3 are imported by name when a pickle that
names them is read).
"""

from __future__ import annotations

import _compat_pickle
import hashlib
import importlib
import io
import os
import pickle
import stat
import zipfile
from pathlib import Path
from typing import Any, BinaryIO

__all__ = [
    "ALLOWED_CHECKPOINT",
    "ALLOWED_DATA",
    "ALLOWED_MODEL",
    "MAX_MODEL_DATA_BYTES",
    "MAX_MODEL_ZIP_BYTES",
    "FileRefused",
    "RestrictedUnpickler",
    "UnsafePickleError",
    "check_zip_sizes",
    "file_sha256",
    "load_pickle",
    "load_pickle_file",
    "open_regular",
    "read_regular",
]


class UnsafePickleError(pickle.UnpicklingError):
    """A pickle names a callable outside the allow-list (it could run arbitrary code)."""


class FileRefused(ValueError):
    """A file that is not a regular file, or larger (or inflating to more) than its cap."""


def _pairs(module: str, *names: str) -> set[tuple[str, str]]:
    return {(module, name) for name in names}


#: numpy arrays, scalars and dtypes (module names of numpy 1.x and 2.x), and the bytes of a protocol-2 pickle.
NUMPY_DATA = frozenset(
    {pair for core in ("numpy.core", "numpy._core") for pair in _pairs(f"{core}.multiarray", "_reconstruct", "scalar")}
    | {(f"{core}.numeric", "_frombuffer") for core in ("numpy.core", "numpy._core")}
    | _pairs("numpy", "dtype", "ndarray", "float16", "float32", "float64", "int8", "int16", "int32", "int64")
    | _pairs("numpy", "uint8", "uint16", "uint32", "uint64", "bool_")
    | {("_codecs", "encode")}
)

#: Plain containers.
CONTAINERS = frozenset(
    _pairs("collections", "OrderedDict", "deque") | _pairs("builtins", "set", "frozenset", "slice", "complex")
)

#: The random state a gymnasium space carries: a Generator on a bit generator seeded by a SeedSequence.
NUMPY_RANDOM = frozenset(
    _pairs("numpy.random._pickle", "__generator_ctor", "__bit_generator_ctor", "__randomstate_ctor")
    | _pairs("numpy.random.bit_generator", "SeedSequence", "__pyx_unpickle_SeedSequence")
    | _pairs("numpy.random._pcg64", "PCG64", "PCG64DXSM")
    | _pairs("numpy.random._mt19937", "MT19937")
    | _pairs("numpy.random._philox", "Philox")
    | _pairs("numpy.random._sfc64", "SFC64")
)

#: gymnasium's spaces.
SPACES = frozenset(
    {
        (f"gymnasium.spaces.{module}", name)
        for module, name in (
            ("box", "Box"),
            ("dict", "Dict"),
            ("discrete", "Discrete"),
            ("multi_discrete", "MultiDiscrete"),
            ("multi_binary", "MultiBinary"),
            ("tuple", "Tuple"),
        )
    }
)

#: Everything that is data, not a class of SB3 or torch.
ALLOWED_DATA = NUMPY_DATA | CONTAINERS | NUMPY_RANDOM | SPACES

#: What the `policy_class`, `policy_kwargs` and spaces of a model.zip name: SB3 2.x policy classes (with the
#: aliases of `stable_baselines3.{sac,td3}.policies`), feature extractors, torch activations and optimisers.
MODEL_CLASSES = frozenset(
    _pairs(
        "stable_baselines3.common.policies", "ActorCriticPolicy", "ActorCriticCnnPolicy", "MultiInputActorCriticPolicy"
    )
    | _pairs("stable_baselines3.sac.policies", "SACPolicy", "MlpPolicy", "CnnPolicy", "MultiInputPolicy")
    | _pairs("stable_baselines3.td3.policies", "TD3Policy", "MlpPolicy", "CnnPolicy", "MultiInputPolicy")
    | _pairs("stable_baselines3.common.torch_layers", "FlattenExtractor", "CombinedExtractor", "NatureCNN")
    | _pairs(
        "torch.nn.modules.activation",
        "ReLU",
        "ReLU6",
        "LeakyReLU",
        "ELU",
        "CELU",
        "SELU",
        "GELU",
        "SiLU",
        "Mish",
        "Tanh",
        "Sigmoid",
        "Softplus",
        "Softsign",
        "Hardtanh",
        "Hardswish",
        "Hardsigmoid",
    )
    | {
        (f"torch.optim.{name.lower()}", name)
        for name in ("Adam", "AdamW", "RMSprop", "SGD", "Adamax", "NAdam", "RAdam")
    }
    | {("stable_baselines3.common.sb2_compat.rmsprop_tf_like", "RMSpropTFLike")}
)

#: A model.zip read for inference.
ALLOWED_MODEL = ALLOWED_DATA | MODEL_CLASSES

#: VecNormalize statistics as SB3 pickles them.
VEC_NORMALIZE = frozenset(
    {
        ("stable_baselines3.common.vec_env.vec_normalize", "VecNormalize"),
        ("stable_baselines3.common.running_mean_std", "RunningMeanStd"),
    }
)

#: The learning state of a checkpoint (model.zip entries inference replaces, replay buffers, VecNormalize).
TRAINING_STATE = frozenset(
    _pairs("stable_baselines3.common.utils", "FloatSchedule", "LinearSchedule", "ConstantSchedule")
    | _pairs("stable_baselines3.common.type_aliases", "TrainFreq", "TrainFrequencyUnit")
    | _pairs(
        "stable_baselines3.common.buffers", "ReplayBuffer", "DictReplayBuffer", "RolloutBuffer", "DictRolloutBuffer"
    )
    | _pairs(
        "stable_baselines3.common.noise", "NormalActionNoise", "OrnsteinUhlenbeckActionNoise", "VectorizedActionNoise"
    )
    | {("torch", "device")}
    | VEC_NORMALIZE
)

#: A training checkpoint (mobman-train --resume adds its own schedule class).
ALLOWED_CHECKPOINT = ALLOWED_MODEL | TRAINING_STATE


class RestrictedUnpickler(pickle.Unpickler):
    """An unpickler that resolves only the exact (module, name) pairs of `allowed`, or returns the stand-in
    `substitutes` gives for a pair (without importing anything); see the module docstring."""

    def __init__(
        self,
        file: BinaryIO,
        allowed: frozenset[tuple[str, str]],
        substitutes: dict[tuple[str, str], Any] | None = None,
        what: str = "this file",
    ) -> None:
        super().__init__(file)
        self.allowed = allowed
        self.substitutes = substitutes or {}
        self.what = what

    def find_class(self, module: str, name: str) -> Any:
        if "." in name:
            raise UnsafePickleError(
                f"refused to load {module}.{name} (a dotted name, which pickle would resolve attribute by "
                f"attribute; {self.what} names classes and functions directly)"
            )
        # Python 2 names, mapped as pickle maps them, then checked like any other
        pair = _compat_pickle.NAME_MAPPING.get(
            (module, name), (_compat_pickle.IMPORT_MAPPING.get(module, module), name)
        )
        if pair in self.substitutes:
            return self.substitutes[pair]
        if pair not in self.allowed:
            raise UnsafePickleError(f"refused to load {module}.{name} (not in the allow-list of {self.what})")
        try:
            return getattr(importlib.import_module(pair[0]), pair[1])
        except (ImportError, AttributeError) as exc:
            raise pickle.UnpicklingError(f"{pair[0]}.{pair[1]} is not available here ({exc})") from None


def load_pickle(
    data: bytes,
    allowed: frozenset[tuple[str, str]],
    substitutes: dict[tuple[str, str], Any] | None = None,
    what: str = "this file",
) -> Any:
    """The object pickled in `data`, through `RestrictedUnpickler` (UnsafePickleError for a refused name)."""
    return RestrictedUnpickler(io.BytesIO(data), allowed, substitutes, what).load()


def open_regular(path: Path, max_bytes: int | None = None, what: str = "file") -> BinaryIO:
    """`path` opened for reading if it is a regular file (of at most `max_bytes`, if given); `FileRefused` (a
    ValueError) naming the file, what it is and the cap otherwise. A FIFO is never opened, so it cannot hang
    the caller; a device such as /dev/zero is refused."""
    path = Path(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise FileRefused(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode) else "a device"
        raise FileRefused(
            f"{path} is {kind}, not a regular file; the {what} must be a plain file: copy it again from the run"
        )
    if max_bytes is not None and st.st_size > max_bytes:
        raise FileRefused(
            f"{path} holds {st.st_size} bytes; a {what} is at most {max_bytes} bytes: copy it again from the run"
        )
    f = os.fdopen(os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)), "rb")
    if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):  # replaced between stat and open
        f.close()
        raise FileRefused(f"{path} is not a regular file; the {what} must be a plain file")
    return f


def read_regular(path: Path, max_bytes: int, what: str = "file") -> bytes:
    """The bytes of `path` if it is a regular file of at most `max_bytes` (`open_regular`)."""
    with open_regular(path, max_bytes, what) as f:
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise FileRefused(f"{path} grew beyond {max_bytes} bytes while it was read; a {what} is at most that")
    return data


def load_pickle_file(path: Path, allowed: frozenset[tuple[str, str]], what: str) -> Any:
    """The object pickled in the regular file `path`, through `RestrictedUnpickler` (read as a stream: a
    replay buffer may be large)."""
    with open_regular(path, None, what) as f:
        return RestrictedUnpickler(f, allowed, what=what).load()


#: Caps on a model.zip: its JSON `data` entry (a few hundred kB for mobman's agents) and all entries together
#: (the weights: 3.3 MB for the shipped SAC), decompressed, as the zip declares them.
MAX_MODEL_DATA_BYTES = 64 * 2**20
MAX_MODEL_ZIP_BYTES = 1024 * 2**20


def check_zip_sizes(zf: zipfile.ZipFile, path: Path, caps: dict[str, int], total: int) -> None:
    """Refuse a zip whose entry `name` declares more than `caps[name]` bytes decompressed, or whose entries
    declare more than `total` together (`FileRefused` naming the file, the entry and the cap)."""
    sizes = {info.filename: info.file_size for info in zf.infolist()}
    for name, cap in caps.items():
        if sizes.get(name, 0) > cap:
            raise FileRefused(
                f"{path}: entry {name!r} inflates to {sizes[name]} bytes; at most {cap} are read: copy the file "
                f"again from the training run"
            )
    if sum(sizes.values()) > total:
        raise FileRefused(
            f"{path}: its entries inflate to {sum(sizes.values())} bytes; at most {total} are read: copy the file "
            f"again from the training run"
        )


def file_sha256(path: Path) -> str:
    """The SHA-256 of a regular file's bytes (hex), read in 1 MiB blocks (`open_regular`: never a FIFO or a
    device)."""
    h = hashlib.sha256()
    with open_regular(path, None, "file") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


#: The local-file-header signature a zip archive starts with (torch saves `policy.pth` as such an archive).
_ZIP_MAGIC = b"PK\x03\x04"


def check_nested_zip_sizes(zf: zipfile.ZipFile, path: Path, total: int) -> None:
    """Refuse a zip whose entries that are themselves zip archives declare records that inflate, together with
    the outer entries, to more than `total` bytes (`FileRefused` naming the file, the entry and the cap).

    Why: torch saves `policy.pth` as a zip inside model.zip and `torch.load` inflates each of its records to
    the size the inner archive declares; a 3.6 MB model.zip whose `policy.pth` declared one 2 GiB record of
    zeros took 52 s and 2.4 GB before torch refused it, though `check_zip_sizes` (the outer sizes) passed it.
    How, without inflating any inner record: each outer entry is opened as a stream (`ZipFile.open`: seekable,
    read in chunks of at most 16 MiB, and at most its own declared size, which `check_zip_sizes` capped);
    one starting with the zip signature is parsed as a zip, which reads only its end record and central
    directory, whose declared sizes are summed. One level: torch nests no archive inside the inner one. An
    entry that starts like a zip but is not one is refused (nothing could bound what a reader makes of it)."""
    declared = sum(info.file_size for info in zf.infolist())
    for info in zf.infolist():
        with zf.open(info) as entry:
            if entry.read(len(_ZIP_MAGIC)) != _ZIP_MAGIC:
                continue
            entry.seek(0)
            try:
                with zipfile.ZipFile(entry) as inner:
                    size = sum(record.file_size for record in inner.infolist())
            except (zipfile.BadZipFile, ValueError, OSError) as exc:
                raise FileRefused(
                    f"{path}: entry {info.filename!r} starts like a zip archive but is not one ({exc}): copy the "
                    f"file again from the training run"
                ) from None
        declared += size
        if declared > total:
            raise FileRefused(
                f"{path}: entry {info.filename!r} is an archive whose records inflate to {size} bytes (all entries "
                f"together: {declared}); at most {total} are read: copy the file again from the training run"
            )
