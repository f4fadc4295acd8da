"""What a compensator learned, in a plain numeric ``.npz`` file (never pickle).

:func:`save_state` writes named float arrays atomically (a temporary file
beside the target, then a rename: a crash never leaves half a file).
:func:`load_state` reads with ``numpy.load(..., allow_pickle=False)`` and
refuses, naming the file and the problem, with a :class:`ConfigError`:

- a missing file, or one that is not an ``.npz`` archive (an ``.npy`` array,
  text, a truncated zip);
- an entry that is not a numeric array (strings, objects);
- a missing key, or a key the compensator does not know;
- an array of the wrong shape ("expected (2, 6), got (2, 5)");
- non-finite entries (how many, and the index of the first).

An expected shape may hold ``None`` for a length that varies (the ILC's
feedforward follows the run's length).
"""
from __future__ import annotations

import os
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import numpy.typing as npt

from cnc_contour_control.core.errors import ConfigError

#: An expected shape: a length per dimension, None where any length is accepted.
Shape = tuple[int | None, ...]
FloatArray = npt.NDArray[np.float64]
_ZIP_MAGIC = b"PK"  # a zip starts with a local header (PK\3\4), an empty one with its end record (PK\5\6)
_NPY_MAGIC = b"\x93NUMPY"


def save_state(path: str | Path, arrays: Mapping[str, npt.ArrayLike]) -> None:
    """Write ``arrays`` (name -> float array) to the ``.npz`` file ``path``, atomically.

    The name is kept as given (``numpy.savez`` would append ``.npz`` to a bare name).
    """
    target = Path(path)
    values = {name: np.asarray(value, dtype=np.float64) for name, value in arrays.items()}
    handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent or ".")
    try:
        with os.fdopen(handle, "wb") as stream:
            np.savez(stream, **values)  # type: ignore[arg-type]  # NumPy's stub: a ** mapping might name allow_pickle
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def load_state(path: str | Path, expected: Mapping[str, Shape], what: str) -> dict[str, FloatArray]:
    """The arrays of the ``.npz`` file ``path``, each checked against ``expected`` (name -> shape).

    Parameters
    ----------
    path : str or Path
        The file.
    expected : Mapping[str, tuple]
        Every key the file must hold, with its shape (``None``: any length).
    what : str
        What the file is, for the errors (``"neural compensator weights"``).

    Returns
    -------
    dict of str to ndarray
        float64 copies, in ``expected``'s keys.

    Raises
    ------
    ConfigError
        Naming the file and the problem (see the module docstring).
    """
    file = Path(path)
    name = f"{what} {str(file)!r}"
    arrays = _read_archive(file, name)
    missing = [key for key in expected if key not in arrays]
    if missing:
        raise ConfigError(f"{name} lacks {missing[0]!r}; it holds {sorted(arrays)}, expected {sorted(expected)}")
    unknown = sorted(set(arrays) - set(expected))
    if unknown:
        raise ConfigError(f"{name} holds {unknown} that a {what} does not have; expected {sorted(expected)}")
    return {key: _checked_array(name, key, arrays[key], shape) for key, shape in expected.items()}


def _read_archive(file: Path, name: str) -> dict[str, np.ndarray]:
    """Every array of the archive ``file`` (read in full), or a ConfigError naming the problem."""
    if not file.is_file():
        raise ConfigError(f"{name} does not exist")
    try:
        with file.open("rb") as stream:
            magic = stream.read(len(_NPY_MAGIC))
    except OSError as err:
        raise ConfigError(f"{name} cannot be read: {err.strerror}") from err
    if magic.startswith(_NPY_MAGIC):
        raise ConfigError(f"{name} is a single .npy array, not an .npz archive")
    if not magic.startswith(_ZIP_MAGIC):
        raise ConfigError(f"{name} is not a numeric .npz archive (it does not start as a zip file)")
    try:
        loaded = np.load(file, allow_pickle=False)
        if isinstance(loaded, np.lib.npyio.NpzFile):
            with loaded as archive:
                return {key: archive[key] for key in archive.files}
    except ValueError as err:
        reason = "holds an object array (pickled data is refused)" if "pickle" in str(err) else \
            f"is not a numeric .npz archive ({_one_line(err)})"
        raise ConfigError(f"{name} {reason}") from err
    except (OSError, EOFError, zipfile.BadZipFile) as err:
        raise ConfigError(f"{name} is not a numeric .npz archive ({_one_line(err)})") from err
    raise ConfigError(f"{name} is not an .npz archive")


def _checked_array(name: str, key: str, array: np.ndarray, shape: Shape) -> FloatArray:
    """``array`` as float64 if numeric, of ``shape`` and finite; a ConfigError otherwise."""
    if array.dtype.kind not in "fiu":
        raise ConfigError(f"{name}: {key!r} must hold numbers, got dtype {array.dtype}")
    if len(shape) != array.ndim or any(want is not None and want != got for want, got in zip(shape, array.shape)):
        wanted = "(" + ", ".join("any" if n is None else str(n) for n in shape) + ("," if len(shape) == 1 else "") + ")"
        raise ConfigError(f"{name}: {key!r} has shape {array.shape}, expected {wanted}")
    values = array.astype(np.float64)
    bad = ~np.isfinite(values)
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ConfigError(f"{name}: {key!r} holds {int(bad.sum())} non-finite entries (the first at index {first})")
    return values


def _one_line(err: Exception) -> str:
    return " ".join(str(err).split())
