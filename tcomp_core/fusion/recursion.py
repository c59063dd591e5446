"""Linear recursions over long records without a Python loop over samples.

``x_j = A x_{j-1} + u_j`` is solved in the Schur basis of A as first-order
:func:`scipy.signal.lfilter` calls; matrix powers come from the eigendecomposition when it is
well conditioned. These are the workhorses of the steady-state Kalman filter and RTS smoother.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray
from scipy import signal

from ..compiled import compile_loops

__all__ = [
    "MAX_EIGENVECTOR_CONDITION",
    "MODAL_CONDITION",
    "ModalRecursion",
    "apply_matrix",
    "decay_horizon",
    "driven_states",
    "linear_recursion",
    "matrix_powers",
]

#: Batches up to this many samples run through :class:`ModalRecursion` as one product.
SHORT_BATCH = 64
#: Largest condition number of the eigenvectors for which a recursion runs in the eigenbasis
#: (its rounding grows with it; beyond, the Schur basis, unitary, is used).
MODAL_CONDITION = 1e6
#: Largest condition number of the eigenvectors for which matrix powers come from them.
MAX_EIGENVECTOR_CONDITION = 1e8
#: Least states × columns for which an ill-conditioned recursion runs sample by sample (one
#: matrix product each) instead of in the Schur basis (n²/2 array operations over the whole
#: record). Measured on 10 000 samples: n = 35 with 35 columns 2.0 s Schur against 0.15 s,
#: 16 × 16 0.31 against 0.044, 10 × 10 0.12 against 0.040; 35 × 1 0.037 against 0.035 and
#: 10 × 1 0.010 against 0.029.
SAMPLE_LOOP_SIZE = 64


def apply_matrix(matrix: NDArray, array: NDArray) -> NDArray:
    """``matrix`` (a, b) applied along the first axis of ``array`` (b, ...) → (a, ...).

    A matrix product (BLAS), with the trailing axes flattened into one. BLAS runs
    single-threaded here (``tcomp_core`` sets ``OPENBLAS_NUM_THREADS``): threads spread these
    small-by-long products over a loaded machine's cores and made them ten times slower, while
    one thread does them several times faster than elementwise sums.
    """
    rows = matrix.shape[0]
    flat = array.reshape(array.shape[0], -1)
    return (matrix @ flat).reshape((rows, *array.shape[1:]))


def linear_recursion(
    matrix: NDArray[np.float64], inputs: NDArray[np.float64], initial: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Run ``x_j = A x_{j-1} + u_j`` for j = 1..M without a Python loop over samples.

    In the eigenbasis of A (``A = V Λ V⁻¹``, when V is well conditioned) every mode is a
    first-order recursion of its own: one :func:`scipy.signal.lfilter` call per mode, one of
    each complex-conjugate pair. Otherwise, in the Schur basis ``A = U T Uᴴ`` (T upper
    triangular, U unitary), each component is a first-order recursion driven by the inputs and
    by the components after it, solved from the last component back to the first (n² array
    operations instead of n).

    Parameters
    ----------
    matrix : ndarray, shape (n, n)
        A; a bounded result needs its eigenvalues inside the unit circle.
    inputs : ndarray, shape (n, M, m)
        u_1..u_M, component first, for m independent columns propagated together.
    initial : ndarray, shape (n, m)
        x_0.

    Returns
    -------
    ndarray, shape (n, M, m)
        x_1..x_M.
    """
    eigenvalues, vectors = np.linalg.eig(matrix)
    if np.linalg.cond(vectors) <= MODAL_CONDITION:
        return _eigenbasis_recursion(eigenvalues, vectors, inputs, initial)
    if inputs.shape[0] * inputs.shape[2] >= SAMPLE_LOOP_SIZE:
        return _sample_recursion(matrix, inputs, initial)
    return _schur_recursion(matrix, inputs, initial)


def driven_states(
    matrix: NDArray[np.float64],
    input_matrix: NDArray[np.float64],
    inputs: NDArray[np.float64],
    initial: NDArray[np.float64],
) -> Callable[[slice, int], NDArray[np.float64]]:
    """``x_j = A x_{j-1} + B u_j`` (j = 1..M, one column of inputs), its states on demand.

    :func:`linear_recursion` of ``B u`` where the caller forms only the state components it
    needs: in the eigenbasis the modes are driven by ``(V⁻¹ B) u`` (one small product with the
    inputs) and ``V[rows]`` maps them back, where forming every state costs two products
    with n rows. Asked twice for the same rows and count, the returned function gives the same
    array bit for bit (the product is the same).

    Parameters
    ----------
    matrix : ndarray, shape (n, n)
        A.
    input_matrix : ndarray, shape (n, m)
        B.
    inputs : ndarray, shape (m, M)
        u_1..u_M.
    initial : ndarray, shape (n,)
        x_0.

    Returns
    -------
    callable
        ``states(rows, count)``: the components ``rows`` of x_1..x_count, shape (r, count).
    """
    eigenvalues, vectors = np.linalg.eig(matrix)
    if np.linalg.cond(vectors) > MODAL_CONDITION:
        driven = apply_matrix(input_matrix, inputs)[:, :, None]
        full = linear_recursion(matrix, driven, initial[:, None])[:, :, 0]
        return lambda rows, count: full[rows, :count]
    kept = eigenvalues.imag >= 0.0  # real ones, and one of each conjugate pair
    weight = np.where(eigenvalues.imag[kept] > 0.0, 2.0, 1.0)
    inverse = np.linalg.inv(vectors)[kept]
    drive = apply_matrix(inverse @ input_matrix, inputs)
    start = inverse @ initial
    modes = np.empty_like(drive)
    for i, pole in enumerate(eigenvalues[kept]):
        modes[i], _ = signal.lfilter([1.0], [1.0, -pole], drive[i], zi=pole * start[i : i + 1])
    back = vectors[:, kept] * weight
    return lambda rows, count: np.asarray(
        apply_matrix(back[rows], np.ascontiguousarray(modes[:, :count])).real
    )


def _sample_recursion(
    matrix: NDArray[np.float64], inputs: NDArray[np.float64], initial: NDArray[np.float64]
) -> NDArray[np.float64]:
    """:func:`linear_recursion` one sample at a time (a matrix product each)."""
    steps = np.moveaxis(inputs, 1, 0)  # (M, n, m): sample first, a view
    states = np.empty(steps.shape)
    state = np.asarray(initial, dtype=np.float64)
    for k, step in enumerate(steps):
        state = matrix @ state
        state += step
        states[k] = state
    return np.moveaxis(states, 0, 1)


def _eigenbasis_recursion(
    eigenvalues: NDArray[np.complex128],
    vectors: NDArray[np.complex128],
    inputs: NDArray[np.float64],
    initial: NDArray[np.float64],
) -> NDArray[np.float64]:
    """:func:`linear_recursion` mode by mode; one mode of each complex-conjugate pair."""
    kept = eigenvalues.imag >= 0.0  # real ones, and one of each conjugate pair
    weight = np.where(eigenvalues.imag[kept] > 0.0, 2.0, 1.0)
    inverse = np.linalg.inv(vectors)[kept]
    drive = apply_matrix(inverse, inputs)
    start = inverse @ initial
    modes = np.empty_like(drive)
    for i, pole in enumerate(eigenvalues[kept]):
        modes[i], _ = signal.lfilter(
            [1.0], [1.0, -pole], drive[i], axis=0, zi=pole * start[i : i + 1]
        )
    return np.asarray(apply_matrix(vectors[:, kept] * weight, modes).real)


def _schur_recursion(
    matrix: NDArray[np.float64], inputs: NDArray[np.float64], initial: NDArray[np.float64]
) -> NDArray[np.float64]:
    """:func:`linear_recursion` in the Schur basis, from the last component back to the first."""
    upper, basis = scipy.linalg.schur(matrix, output="complex")
    n = matrix.shape[0]
    drive = apply_matrix(basis.conj().T, inputs)
    start = basis.conj().T @ initial
    states = np.empty_like(drive)
    delayed = np.empty_like(drive)  # z_j[k-1], filled as components are solved
    for i in range(n - 1, -1, -1):
        forcing = drive[i]
        for j in range(i + 1, n):
            if upper[i, j] != 0.0:
                forcing = forcing + upper[i, j] * delayed[j]
        pole = upper[i, i]
        states[i], _ = signal.lfilter(
            [1.0], [1.0, -pole], forcing, axis=0, zi=pole * start[i : i + 1]
        )
        delayed[i, 0] = start[i]
        delayed[i, 1:] = states[i, :-1]
    return np.asarray(apply_matrix(basis, states).real)


def matrix_powers(
    matrix: NDArray[np.float64], count: int, rows: slice = slice(None)
) -> NDArray[np.float64]:
    """``(matrix**k)[rows]`` for k = 0..count-1 as an array (r, count, n).

    From the eigendecomposition ``A = V Λ V⁻¹`` when V is well conditioned (a few elementwise
    products), else by running the recursion on the identity.
    """
    n = matrix.shape[0]
    eigenvalues, vectors = np.linalg.eig(matrix)
    if np.linalg.cond(vectors) > MAX_EIGENVECTOR_CONDITION:
        powers = linear_recursion(matrix, np.zeros((n, count - 1, n)), np.eye(n))
        return np.concatenate((np.eye(n)[:, None], powers), axis=1)[rows]
    inverse = np.linalg.inv(vectors)
    steps = eigenvalues[:, None] ** np.arange(count)  # (n, count)
    left = vectors[rows]
    # Σ_i left[r, i] λ_i^k inverse[i, j] as one product over i.
    scaled = steps[:, :, None] * inverse[:, None, :]  # (n, count, n)
    return apply_matrix(left, scaled).real


def decay_horizon(matrix: NDArray[np.float64], count: int) -> int:
    """Samples after which ``matrix**k`` has decayed below 1e-13 (at most ``count``)."""
    radius = float(np.max(np.abs(np.linalg.eigvals(matrix))))
    if radius >= 1.0 - 1e-12:
        return count
    return int(min(count, math.ceil(math.log(1e-13) / math.log(max(radius, 1e-300))) + 1))


def _modal_runs(
    poles: NDArray[np.complex128],
    drive: NDArray[np.complex128],
    start: NDArray[np.complex128],
    modes: NDArray[np.complex128],
) -> None:
    # modes[i, 0] = start[i], modes[i, j + 1] = poles[i] modes[i, j] + drive[i, j]: every
    # mode's first-order recursion in one compiled pass (an lfilter call per mode cost more in
    # its set-up than in the 1 250 samples of a batch).
    for i in range(poles.size):
        pole = poles[i]
        value = start[i]
        modes[i, 0] = value
        for j in range(drive.shape[1]):
            value = pole * value + drive[i, j]
            modes[i, j + 1] = value


@functools.cache
def _modal_kernel() -> Callable[..., Any]:
    """:func:`_modal_runs`, compiled where numba is installed (once per process, on disk)."""
    return compile_loops(_modal_runs)[0]


class ModalRecursion:
    """A fixed linear system run batch by batch at compiled speed, its state carried over.

    ``x_{k+1} = A x_k + B u_k``, ``out_k = C x_k + D u_k``. In the eigenbasis of A
    (``A = V Λ V⁻¹``) every mode is a first-order recursion driven by ``(V⁻¹ B) u``: all of
    them in one compiled loop (:func:`_modal_runs`; one of each complex-conjugate pair: the
    other is its conjugate), whatever the batch length. With ill-conditioned eigenvectors it runs
    :func:`linear_recursion` in a Schur basis instead (slower per call, as accurate).

    Parameters
    ----------
    a : ndarray, shape (n, n)
    b : ndarray, shape (n, m)
    c : ndarray, shape (p, n)
    d : ndarray, shape (p, m)
    """

    def __init__(
        self,
        a: NDArray[np.float64],
        b: NDArray[np.float64],
        c: NDArray[np.float64],
        d: NDArray[np.float64],
    ) -> None:
        self._a, self._b, self._c, self._d = a, b, c, d
        eigenvalues, vectors = np.linalg.eig(a)
        self._modal = bool(np.linalg.cond(vectors) <= MODAL_CONDITION)
        if not self._modal:
            return
        # A real matrix's eigenvalues come in exact conjugate pairs (LAPACK): keep the real
        # ones and the upper member of each pair, counted twice through the real part.
        kept = eigenvalues.imag >= 0.0
        weight = np.where(eigenvalues.imag[kept] > 0.0, 2.0, 1.0)
        inverse = np.linalg.inv(vectors)[kept]
        self._poles = eigenvalues[kept]
        self._drive = inverse @ b  # (k, m)
        self._project = inverse  # x -> z, (k, n)
        self._read = (c @ vectors[:, kept]) * weight  # z -> out, (p, k)
        self._rebuild = vectors[:, kept] * weight  # z -> x, (n, k)
        lags = np.arange(SHORT_BATCH + 1)
        self._powers = self._poles[:, None] ** lags  # λ^j, (k, S + 1)
        delay = lags[:, None] - 1 - lags[None, :-1]  # j - 1 - i, (S + 1, S)
        self._convolution = np.where(
            delay >= 0, self._powers[:, np.clip(delay, 0, None)], 0.0
        )  # (k, S + 1, S)

    def run(
        self, inputs: NDArray[np.float64], initial: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Outputs (p, M) of the inputs (m, M) from state ``initial`` (n,), and the next state.

        Returns
        -------
        outputs : ndarray, shape (p, M)
            ``C x_k + D u_k`` for k = 0..M-1.
        state : ndarray, shape (n,)
            ``x_M``.
        """
        direct = self._d @ inputs
        if not self._modal:
            runs = linear_recursion(self._a, (self._b @ inputs)[:, :, None], initial[:, None])
            states = np.concatenate((initial[:, None], runs[:, :-1, 0]), axis=1)
            return self._c @ states + direct, runs[:, -1, 0]
        count = inputs.shape[1]
        drive = self._drive @ inputs  # (k, M) complex
        start = self._project @ initial
        if count <= SHORT_BATCH:
            # z_j = λ^j z_0 + Σ_{i<j} λ^(j-1-i) u_i as one product: cheaper than a call per
            # mode for the few samples a real-time batch holds.
            modes = self._powers[:, : count + 1] * start[:, None] + np.einsum(
                "kji,ki->kj", self._convolution[:, : count + 1, :count], drive
            )
        else:
            modes = np.empty((self._poles.size, count + 1), dtype=np.complex128)
            _modal_kernel()(self._poles, np.ascontiguousarray(drive), start, modes)
        outputs = (self._read @ modes[:, :-1]).real + direct
        return outputs, (self._rebuild @ modes[:, -1]).real
