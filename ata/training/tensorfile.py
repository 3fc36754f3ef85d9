"""Reading a checkpoint that ``torch.save`` wrote without importing torch: its tensors as numpy
arrays, the rest as plain data.

A checkpoint is a zip archive: ``<name>/data.pkl`` the pickled object, where each tensor is a call
of ``torch._utils._rebuild_tensor_v2`` on a storage that names an entry ``<name>/data/<key>`` of
raw little-endian bytes. The unpickler here admits the globals an ata checkpoint is made of and
nothing else (as ``torch.load(..., weights_only=True)`` admits tensors and plain data alone): an
``OrderedDict``, the tensor rebuild and the storage types of numeric dtypes. Any other global is
refused before anything of it runs.

Evaluation reads its weights this way, so a run of a learned method starts without torch's import
(about a second); training reads with torch (``read_checkpoint``).
"""

from __future__ import annotations

import collections
import pickle
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

STORAGES = {"FloatStorage": np.float32, "DoubleStorage": np.float64, "HalfStorage": np.float16,
            "LongStorage": np.int64, "IntStorage": np.int32, "ShortStorage": np.int16,
            "CharStorage": np.int8, "ByteStorage": np.uint8, "BoolStorage": np.bool_}
"""The storage types a checkpoint may hold, and their numpy dtypes."""


class ForeignGlobal(pickle.UnpicklingError):
    """The pickle names a global other than an ata checkpoint's."""


class _Storage:
    """A storage type named in the pickle: its numpy dtype."""

    def __init__(self, dtype: type):
        self.dtype = np.dtype(dtype)


def _rebuild_tensor(storage: np.ndarray, offset: int, size: tuple, stride: tuple,
                    requires_grad: bool = False, hooks: Any = None, *rest: Any) -> np.ndarray:
    """``torch._utils._rebuild_tensor_v2`` as a numpy array (a copy, contiguous)."""
    if not size:
        return np.array(storage[offset])
    end = offset + sum((n - 1) * s for n, s in zip(size, stride)) + 1
    if offset < 0 or any(n < 0 or s < 0 for n, s in zip(size, stride)) or \
            (min(size) > 0 and end > storage.size):
        raise pickle.UnpicklingError("a tensor reaches beyond its storage")
    item = storage.itemsize
    view = np.lib.stride_tricks.as_strided(storage[offset:], shape=tuple(size),
                                           strides=tuple(s * item for s in stride))
    return np.ascontiguousarray(view)


class _Unpickler(pickle.Unpickler):
    def __init__(self, data: bytes, archive: zipfile.ZipFile, prefix: str):
        import io
        super().__init__(io.BytesIO(data))
        self.archive, self.prefix = archive, prefix
        self.storages: dict[str, np.ndarray] = {}

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) == ("collections", "OrderedDict"):
            return collections.OrderedDict
        if (module, name) == ("torch._utils", "_rebuild_tensor_v2"):
            return _rebuild_tensor
        if module == "torch" and name in STORAGES:
            return _Storage(STORAGES[name])
        raise ForeignGlobal(f"unsupported global {module}.{name}")

    def persistent_load(self, pid: Any) -> np.ndarray:
        if not (isinstance(pid, tuple) and len(pid) == 5 and pid[0] == "storage"
                and isinstance(pid[1], _Storage)):
            raise pickle.UnpicklingError(f"unknown persistent id {str(pid)[:80]}")
        _, kind, key, _, numel = pid
        if key not in self.storages:
            raw = self.archive.read(f"{self.prefix}/data/{key}")
            arr = np.frombuffer(raw, dtype=kind.dtype.newbyteorder("<"))
            if arr.size < int(numel):
                raise pickle.UnpicklingError(f"storage {key} is shorter than it says")
            self.storages[key] = arr.astype(kind.dtype, copy=False)
        return self.storages[key]


def load(path: str | Path) -> Any:
    """The object a ``torch.save`` file holds, its tensors as numpy arrays. Raises
    `ForeignGlobal` for a pickle of anything but tensors and plain data, and an exception of
    zipfile or pickle for a file that is not such an archive."""
    with zipfile.ZipFile(path) as archive:
        pickles = [n for n in archive.namelist() if n.endswith("/data.pkl")]
        if len(pickles) != 1:
            raise zipfile.BadZipFile("not a torch checkpoint archive (no single data.pkl)")
        prefix = pickles[0][: -len("/data.pkl")]
        order = f"{prefix}/byteorder"
        if order in archive.namelist() and archive.read(order).strip() != b"little":
            raise pickle.UnpicklingError("a big-endian checkpoint")
        if sys.byteorder != "little":
            raise pickle.UnpicklingError("this reader runs on little-endian machines alone")
        return _Unpickler(archive.read(pickles[0]), archive, prefix).load()
