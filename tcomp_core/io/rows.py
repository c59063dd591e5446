"""Fixed-offset fields of byte rows (serialized messages, MCAP records) without copying."""

from __future__ import annotations

import numpy as np
from numpy.typing import DTypeLike, NDArray

__all__ = ["column"]


def column(rows: NDArray[np.uint8], start: int, dtype: DTypeLike) -> NDArray:
    """Bytes ``start:start+itemsize`` of every row read as one value of ``dtype``.

    Parameters
    ----------
    rows : ndarray of uint8, shape (N, L)
        Rows of bytes; any row stride (a view into a larger buffer is fine).
    start : int
        Byte offset of the field in a row.
    dtype : dtype
        Type of the field, with its byte order (e.g. ``'<u8'``).

    Returns
    -------
    ndarray, shape (N,)
        A strided view when the rows' bytes are contiguous (the usual case), else a copy.
        Unaligned fields are fine; copy the result (``astype``) to get an aligned array.
    """
    width = np.dtype(dtype).itemsize
    part = rows[:, start : start + width]
    if part.strides[1] == 1:
        return part.view(dtype)[:, 0]
    return np.ascontiguousarray(part).view(dtype).ravel()
