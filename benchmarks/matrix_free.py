"""Matrix-free stiffness application by sum factorisation against the assembled matrix.

    python benchmarks/matrix_free.py

One patch (a twisted cube, constant conductivity), p = 2, 3, 4, about 110k
unknowns: the time of one product K x with the assembled CSR matrix (SciPy)
and with a sum-factorised matrix-free operator in NumPy/SciPy (gradients at
the Gauss points by one sparse 1-D product per direction and term, the
metric k det J J^-1 J^-T stored per Gauss point, then the transposed
products), checked against the matrix (relative difference printed).  Memory
per unknown of both, and what they come to at 1M and 4M unknowns: the matrix
holds (2p + 1)^3 entries per row (8-byte values, 4-byte column indices), the
matrix-free operator six metric values per Gauss point ((p + 1)^3 per
element) plus the 1-D tables.  Writes benchmarks/out/matrix_free.json.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from _common import print_table, save_json


def _mode(X, B, axis):
    """X multiplied along ``axis`` by the sparse matrix B."""
    Xm = np.moveaxis(X, axis, 0)
    shape = Xm.shape
    Y = B @ Xm.reshape(shape[0], -1)
    return np.moveaxis(Y.reshape((B.shape[0],) + shape[1:]), 0, axis)


class MatrixFree:
    """K x = sum_kl B_k^T (G_kl * (B_l x)) with B_l = the tensor basis with the derivative in direction l."""

    def __init__(self, problem):
        from geometry.patches.chain import patch_geometry_grid

        space = problem.spaces[0]
        self.shape = space.shape
        self.B = []
        for s in space.dirs:
            self.B.append([sp.csr_matrix(s.B[a][:, : s.nq].T) for a in (0, 1)])  # (nq, n) values, derivatives
        P = problem.model.patches[0]
        x, J, chans = patch_geometry_grid(P, space.qaxes)
        det = np.linalg.det(J)
        Jinv = np.linalg.inv(J)
        w = np.einsum("i,j,k->ijk", *[s.qw for s in space.dirs]).ravel()
        G = np.einsum("nki,nli->nkl", Jinv, Jinv) * (np.abs(det) * w)[:, None, None]
        q = tuple(s.nq for s in space.dirs)
        self.G = {(k, m): np.ascontiguousarray(G[:, k, m]).reshape(q) for k in range(3) for m in range(k, 3)}

    def nbytes(self) -> int:
        return sum(g.nbytes for g in self.G.values()) + sum(b.data.nbytes + b.indices.nbytes + b.indptr.nbytes
                                                            for bb in self.B for b in bb)

    def __call__(self, x):
        X = x.reshape(self.shape)
        B = self.B
        T2 = _mode(X, B[2][0], 2)
        g = [_mode(_mode(T2, B[1][0], 1), B[0][1], 0), _mode(_mode(T2, B[1][1], 1), B[0][0], 0),
             _mode(_mode(_mode(X, B[2][1], 2), B[1][0], 1), B[0][0], 0)]
        G = self.G
        f = [sum(G[min(k, m), max(k, m)] * g[m] for m in range(3)) for k in range(3)]
        y = 0
        for k in range(3):
            Y = f[k]
            for d in (0, 1, 2):
                Y = _mode(Y, B[d][1 if d == k else 0].T.tocsr(), d)
            y = y + Y
        return y.ravel()


def main():
    from geometry import primitives as pr
    from iga import HeatProblem

    rows = []
    for p, n in ((2, 48), (3, 47), (4, 46)):
        N = n - p
        D = pr.refined(pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(p,) * 3), 0.6, axis_point=(0.5, 0.5)), (N,) * 3)
        problem = HeatProblem(D)
        K, _, _ = problem.assemble()
        x = np.random.default_rng(0).standard_normal(K.shape[0])
        t = []
        for _ in range(5):
            t0 = time.perf_counter()
            y = K @ x
            t.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        mf = MatrixFree(problem)
        setup = time.perf_counter() - t0
        tm = []
        for _ in range(3):
            t0 = time.perf_counter()
            z = mf(x)
            tm.append(time.perf_counter() - t0)
        ndof = K.shape[0]
        mat_per = (K.data.nbytes + K.indices.nbytes + K.indptr.nbytes) / ndof
        mf_per = mf.nbytes() / ndof
        rows.append({"p": p, "unknowns": ndof, "matvec s": min(t), "matrix-free s": min(tm),
                     "matrix-free / matvec": min(tm) / min(t), "matrix-free setup s": setup,
                     "rel. difference": float(np.abs(y - z).max() / np.abs(y).max()),
                     "matrix B/unknown": mat_per, "matrix-free B/unknown": mf_per,
                     "matrix GiB at 1M": mat_per * 1e6 / 2**30, "matrix GiB at 4M": mat_per * 4e6 / 2**30,
                     "matrix-free GiB at 1M": mf_per * 1e6 / 2**30, "matrix-free GiB at 4M": mf_per * 4e6 / 2**30})
    print_table(rows, [("p", "d"), ("unknowns", "d"), ("matvec s", ".3f"), ("matrix-free s", ".3f"),
                       ("matrix-free / matvec", ".1f"), ("rel. difference", ".1e"), ("matrix GiB at 1M", ".2f"),
                       ("matrix GiB at 4M", ".2f"), ("matrix-free GiB at 1M", ".2f"),
                       ("matrix-free GiB at 4M", ".2f")])
    save_json("matrix_free.json", rows)


if __name__ == "__main__":
    main()
