"""Small float32 loop nests built on :mod:`navgate.opflow.loops`: generic linear-algebra
kernels used to prove the loop toolchain (executor, modulo scheduler, loop machine).

* :func:`sym_rank1_update`: ``P <- P + s k k^T`` on the upper triangle of a symmetric
  n x n matrix stored row by row (``n (n + 1) / 2`` words), one flat loop over the stored
  elements with ROM tables mapping each to its row and column (no recurrence: II set by the
  ports and units);
* :func:`sparse_matvec`: ``y <- A x`` for a sparse A given by its non-zeros in row order
  (values in memory ``a``, their columns and rows in ROM tables, first/last-of-row flags in
  ROM tables): one accumulator per row, so II is the adder's recurrence;
* :func:`dense_matvec`: ``y <- A x`` (or ``b + A x``: the accumulator starts from a loaded
  word) as a two-level nest (rows, columns) with affine addresses and the accumulator reset
  and stored by the level conditions;
* :func:`dense_matvec_interleaved`: the same sums with the row loop inside: one accumulator
  at distance ``n_rows`` carries every row's sum (each in the same order as
  :func:`dense_matvec`, so the results are the same bits) and II drops to 1 once there are
  as many rows as the adder has stages;
* :func:`scalar_div_sqrt`: a straight-line segment (no loop levels) with a divide, a square
  root and sign flips;
* :func:`sym_rank1_update_loaded`: ``P <- P + (g v) v^T`` with the scale ``g`` read from a
  memory word (written by an earlier segment of a sequence);
* :func:`diag_compare`: ``lt``/``le`` of a symmetric matrix's diagonal against a vector;
* :func:`vector_sqrt_div`: ``z_i <- sqrt(x_i) / y_i`` (the iterative units once per
  iteration: II is the divider's interval);
* :func:`chain_program`: a :class:`~navgate.opflow.sequence.SequenceProgram` of these
  segments over shared memories, with several entry points (a straight-line scalar segment
  feeding a sparse mat-vec feeding a rank-1 update, then a compare).
"""

from __future__ import annotations

import numpy as np

from navgate.opflow.ir import const_name
from navgate.opflow.loops import Acc, Addr, Cond, LoopNest, LOp, Store

__all__ = ["upper_index", "sym_rank1_update", "sparse_matvec", "dense_matvec",
           "dense_matvec_interleaved", "scalar_div_sqrt", "sym_rank1_update_loaded",
           "diag_compare", "vector_sqrt_div", "chain_program"]


def upper_index(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the stored upper triangle (i <= j), row by row."""
    rows, cols = np.triu_indices(n)
    return rows.astype(np.int64), cols.astype(np.int64)


def sym_rank1_update(n: int, scale: float = 1.0) -> LoopNest:
    """``P[i,j] <- P[i,j] + (scale k_i) k_j`` for i <= j (memories ``P``, ``k``); with
    ``scale`` 1 the product is ``k_i k_j``."""
    rows, cols = upper_index(n)
    m = len(rows)
    ops = [LOp("p", "load", ("P",), Addr(None, (1,))),
           LOp("ki", "load", ("k",), Addr("row", (1,))),
           LOp("kj", "load", ("k",), Addr("col", (1,)))]
    a = "ki"
    if scale != 1.0:
        ops.append(LOp("ski", "mul", (const_name(scale), "ki")))
        a = "ski"
    ops += [LOp("kk", "mul", (a, "kj")), LOp("q", "add", ("p", "kk"))]
    return LoopNest(f"sym_rank1_{n}", (m,), {"P": m, "k": n},
                    {"row": rows, "col": cols}, ops, [],
                    [Store("P", Addr(None, (1,)), "q")])


def sparse_matvec(rows, cols, n_rows: int, n_cols: int) -> LoopNest:
    """``y <- A x`` over the non-zeros ``(rows[k], cols[k])`` (sorted by row, every row of
    ``y`` that has non-zeros written, the others left alone); A's values in memory ``a``
    in the same order."""
    rows = np.asarray(rows, np.int64)
    cols = np.asarray(cols, np.int64)
    if len(rows) == 0 or np.any(np.diff(rows) < 0):
        raise ValueError("sparse_matvec needs non-zeros sorted by row")
    first = np.r_[True, rows[1:] != rows[:-1]].astype(np.int64)
    last = np.r_[rows[1:] != rows[:-1], True].astype(np.int64)
    nnz = len(rows)
    ops = [LOp("av", "load", ("a",), Addr(None, (1,))),
           LOp("xv", "load", ("x",), Addr("col", (1,))),
           LOp("pr", "mul", ("av", "xv")),
           LOp("s", "add", ("acc", "pr"))]
    return LoopNest(f"spmv_{n_rows}x{n_cols}_{nnz}", (nnz,),
                    {"a": nnz, "x": n_cols, "y": n_rows},
                    {"col": cols, "row": rows, "first": first, "last": last}, ops,
                    [Acc("acc", const_name(0.0), "s", Cond("table", "first"))],
                    [Store("y", Addr("row", (1,)), "s", Cond("table", "last"))])


def dense_matvec(n_rows: int, n_cols: int, bias: bool = False) -> LoopNest:
    """``y <- A x`` (``y <- b + A x`` with ``bias``: the sum starts from the loaded ``b_i``)
    with A row-major in memory ``A``: levels (row, column)."""
    ops = [LOp("av", "load", ("A",), Addr(None, (n_cols, 1))),
           LOp("xv", "load", ("x",), Addr(None, (0, 1)))]
    arrays = {"A": n_rows * n_cols, "x": n_cols, "y": n_rows}
    init = const_name(0.0)
    if bias:
        ops.append(LOp("bv", "load", ("b",), Addr(None, (1, 0))))
        arrays["b"] = n_rows
        init = "bv"
    ops += [LOp("pr", "mul", ("av", "xv")), LOp("s", "add", ("acc", "pr"))]
    return LoopNest(f"matvec_{n_rows}x{n_cols}{'_bias' if bias else ''}", (n_rows, n_cols),
                    arrays, {}, ops, [Acc("acc", init, "s", Cond("first", 1))],
                    [Store("y", Addr(None, (1, 0)), "s", Cond("last", 1))])


def dense_matvec_interleaved(n_rows: int, n_cols: int) -> LoopNest:
    """``y <- A x`` with levels (column, row): the row sums interleave (accumulator distance
    ``n_rows``), reset at column 0 and stored at the last column."""
    ops = [LOp("av", "load", ("A",), Addr(None, (1, n_cols))),
           LOp("xv", "load", ("x",), Addr(None, (1, 0))),
           LOp("pr", "mul", ("av", "xv")),
           LOp("s", "add", ("acc", "pr"))]
    return LoopNest(f"matvec_il_{n_rows}x{n_cols}", (n_cols, n_rows),
                    {"A": n_rows * n_cols, "x": n_cols, "y": n_rows}, {}, ops,
                    [Acc("acc", const_name(0.0), "s", Cond("at_first", 0), n_rows)],
                    [Store("y", Addr(None, (0, 1)), "s", Cond("at_last", 0))])


def scalar_div_sqrt(array: str = "s") -> LoopNest:
    """Straight line on ``x, y, z = s[0], s[1], s[2]``: ``q = x / y``, ``r = sqrt(z)``;
    ``s[3] <- (-q) r``, ``s[4] <- -r``, ``s[5] <- q + r`` (memory ``s``, 6 words)."""
    ops = [LOp("x", "load", (array,), Addr(None, (), 0)),
           LOp("y", "load", (array,), Addr(None, (), 1)),
           LOp("z", "load", (array,), Addr(None, (), 2)),
           LOp("q", "div", ("x", "y")), LOp("r", "sqrt", ("z",)),
           LOp("nq", "neg", ("q",)), LOp("g", "mul", ("nq", "r")),
           LOp("nr", "neg", ("r",)), LOp("h", "add", ("q", "r"))]
    return LoopNest("scalar_div_sqrt", (), {array: 6}, {}, ops, [],
                    [Store(array, Addr(None, (), 3), "g"), Store(array, Addr(None, (), 4), "nr"),
                     Store(array, Addr(None, (), 5), "h")])


def sym_rank1_update_loaded(n: int, vector: str = "y", scale: tuple = ("s", 3, 6),
                            matrix: str = "P") -> LoopNest:
    """``P[i,j] <- P[i,j] + (g v_i) v_j`` for i <= j, ``g = scale[0][scale[1]]`` (an array of
    ``scale[2]`` words), ``v`` the memory ``vector``."""
    rows, cols = upper_index(n)
    m = len(rows)
    sarr, sword, swords = scale
    ops = [LOp("p", "load", (matrix,), Addr(None, (1,))),
           LOp("vi", "load", (vector,), Addr("row", (1,))),
           LOp("vj", "load", (vector,), Addr("col", (1,))),
           LOp("g", "load", (sarr,), Addr(None, (0,), sword)),
           LOp("gvi", "mul", ("g", "vi")), LOp("kk", "mul", ("gvi", "vj")),
           LOp("q", "add", ("p", "kk"))]
    return LoopNest(f"sym_rank1_loaded_{n}", (m,), {matrix: m, vector: n, sarr: swords},
                    {"row": rows, "col": cols}, ops, [],
                    [Store(matrix, Addr(None, (1,)), "q")])


def diag_compare(n: int, matrix: str = "P", vector: str = "y", out: str = "c") -> LoopNest:
    """``c[i] <- (P[i,i] < v_i)``, ``c[n + i] <- (-v_i <= P[i,i])`` (1.0 or 0.0; 0.0 when a
    NaN is involved) with P's upper triangle stored row by row."""
    rows, cols = upper_index(n)
    diag = np.flatnonzero(rows == cols)
    ops = [LOp("d", "load", (matrix,), Addr("diag", (1,))),
           LOp("v", "load", (vector,), Addr(None, (1,))),
           LOp("a", "lt", ("d", "v")), LOp("nv", "neg", ("v",)),
           LOp("b", "le", ("nv", "d"))]
    return LoopNest(f"diag_compare_{n}", (n,), {matrix: len(rows), vector: n, out: 2 * n},
                    {"diag": diag}, ops, [],
                    [Store(out, Addr(None, (1,)), "a"), Store(out, Addr(None, (1,), n), "b")])


def vector_sqrt_div(n: int, num: str = "x", den: str = "y", out: str = "z") -> LoopNest:
    """``out[i] <- sqrt(num[i]) / den[i]``."""
    ops = [LOp("u", "load", (num,), Addr(None, (1,))),
           LOp("v", "load", (den,), Addr(None, (1,))),
           LOp("r", "sqrt", ("u",)), LOp("q", "div", ("r", "v"))]
    return LoopNest(f"vector_sqrt_div_{n}", (n,), {num: n, den: n, out: n}, {}, ops, [],
                    [Store(out, Addr(None, (1,)), "q")])


def chain_program(n: int, rows, cols):
    """Segments ``prep`` (:func:`scalar_div_sqrt` on ``s``), ``spmv`` (``y <- A x``, the
    sparse pattern ``rows``/``cols``), ``rank1`` (``P <- P + (s[3] y) y^T``), ``cmp``
    (:func:`diag_compare` of P against y into ``c``) and ``norm`` (``z <- sqrt(x) / y``);
    entries ``all`` (prep, spmv, rank1, cmp), ``update`` (rank1, cmp), ``norm`` and
    ``prep``."""
    from navgate.opflow.sequence import SequenceProgram

    segs = {"prep": scalar_div_sqrt(), "spmv": sparse_matvec(rows, cols, n, n),
            "rank1": sym_rank1_update_loaded(n), "cmp": diag_compare(n),
            "norm": vector_sqrt_div(n)}
    arrays: dict = {}
    for nest in segs.values():
        arrays.update(nest.arrays)
    return SequenceProgram(f"chain_{n}", arrays, segs,
                           {"all": ("prep", "spmv", "rank1", "cmp"), "update": ("rank1", "cmp"),
                            "norm": ("norm",), "prep": ("prep",)})
