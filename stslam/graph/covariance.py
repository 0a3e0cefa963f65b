"""Marginal covariances of many smoother variables from one factorisation of its linear system (SPEC 14).

iSAM2 answers a marginal covariance from its Bayes tree, one query at a time:
a pose's in one to ten milliseconds in the kitchen, the joint marginal of a
pose and a landmark in about twenty, and the end of a run asks for hundreds
of each (the re-test of the gated-out observations, the smoothed poses'
covariances). Once a round has asked ``BUILD_AFTER`` of them,
:class:`SystemCovariance` linearises iSAM2's own factors at its
own linearisation point, the system its Bayes tree holds, factors the
information matrix H = AᵀA once (sparse LU) and reads the marginals off solves
H X = E for the variables' unit columns: Cov(a, b) = X_b[rows of a], the same
numbers as iSAM2's queries up to rounding. Where H is too large for one
factorisation to pay (``MAX_NONZEROS``), a solve is not accurate (H's
conditioning is the square of A's; the QR fallback of :mod:`stslam.graph.solver`
exists for such systems) or the factorisation fails, it answers with the
solver's own queries from then on (:class:`SolverCovariance`), as a windowed
smoother does. The smoothed poses' covariances are cut from iSAM2's joint
marginals of many poses at once (:func:`block_marginals`), which cost about
what a few single marginals do.
"""

from __future__ import annotations

import numpy as np

from stslam.graph.prior import slices

__all__ = ["ACCURACY", "BUILD_AFTER", "CHUNK", "JOINT_CHUNK", "JOINT_COST", "KEPT", "MAX_NONZEROS",
           "SolverCovariance", "SystemCovariance", "block_marginals", "covariance_of"]

ACCURACY = 1e-8  # largest |H X − E| of a solve taken as exact (E: unit columns)
CHUNK = 32  # variables solved for at once
# Most nonzeros of H factored here; a larger system asks iSAM2. Measured: a kitchen gated smoother's H (10,095
# rows, 53,000 nonzeros) factors in 0.08 s, 0.85 M entries in L and U; a fridge A-SLAM's (14,227 rows, 172,000
# nonzeros, its door chains) in 25 s with 43 M, where iSAM2's own queries cost a few seconds in all.
MAX_NONZEROS = 100_000
# Questions answered by iSAM2 before the system is factored: linearising every factor (Python ones among them)
# costs about as much as a few hundred of iSAM2's marginals (square_centred, where a round asks a few dozen,
# was 60% slower factoring each round).
BUILD_AFTER = 200
# A joint marginal counts as this many questions: iSAM2 answers one in about five times a marginal's time (kitchen
# seed 0 under isam2: 9.3 ms against 1.1 ms in the gated smoother, 5.8 against 2.3 ms in A-SLAM).
JOINT_COST = 5
JOINT_CHUNK = 128  # variables per joint marginal in block_marginals (a dense joint of 384 rows for poses)
KEPT = 8  # variables whose whole columns (their covariance with every variable) are kept for joints


class SolverCovariance:
    """The same questions answered by the solver's own queries, each marginal asked once."""

    def __init__(self, solver):
        self._solver, self._marginals = solver, {}

    def marginals(self, keys) -> list:
        for key in keys:
            if key not in self._marginals:
                self._marginals[key] = self._solver.marginal(key)
        return [self._marginals[key] for key in keys]

    def marginal(self, key) -> np.ndarray:
        return self.marginals([key])[0]

    def known(self) -> dict:
        """Key → every marginal answered so far."""
        return dict(self._marginals)

    def joint(self, keys) -> np.ndarray:
        return self._solver.joint(keys)


class SystemCovariance:
    """Marginals of the variables of ``solver``'s ``gtsam.ISAM2`` at its current linearisation (module docstring)."""

    def __init__(self, solver, expected: int = 0):
        self._solver, self._fallback = solver, SolverCovariance(solver)
        self._asked = expected  # questions so far, or expected: the system is factored at the BUILD_AFTER-th
        self._built = self._failed = False

    def _build(self) -> None:
        """Linearise and factor the system (module docstring); on failure, ``_failed``."""
        import gtsam
        import scipy.sparse as sp
        from scipy.sparse.linalg import splu

        self._built = True
        isam = self._solver._isam
        theta, held = isam.getLinearizationPoint(), isam.getFactorsUnsafe()
        graph = gtsam.NonlinearFactorGraph()
        for i in range(held.size()):
            factor = held.at(i)
            if factor is not None:  # (removed factors leave an empty slot)
                graph.add(factor)
        linear = graph.linearize(theta)
        keys = list(linear.keyVector())  # the columns' order of sparseJacobian_, each key's dimension wide
        self._at = dict(zip(keys, slices([theta.atVector(key).size for key in keys]), strict=True))
        self._size = sum(rows.size for rows in self._at.values())
        rows, cols, entries = linear.sparseJacobian_()  # 1-based (i, j, a); column size + 1 is b
        rows, cols = rows.astype(np.int64) - 1, cols.astype(np.int64) - 1
        keep = cols < self._size
        A = sp.csc_matrix((entries[keep], (rows[keep], cols[keep])), shape=(int(rows.max()) + 1, self._size))
        self._H = (A.T @ A).tocsc()
        try:
            if self._H.nnz > MAX_NONZEROS:
                raise RuntimeError("too large to pay")
            self._lu = splu(self._H, permc_spec="MMD_AT_PLUS_A")
        except RuntimeError:  # too large, or exactly singular
            self._failed = True
        self._marginals: dict = {}
        self._columns: dict = {}  # key -> its columns of H⁻¹ (size, dim), for the latest KEPT joints' later keys

    def _ready(self, count: int) -> bool:
        """Whether the factored system answers the next ``count`` questions (built once enough are asked)."""
        self._asked += count
        if not self._built and self._asked >= BUILD_AFTER:
            self._build()
        return self._built and not self._failed

    def _solve(self, keys) -> np.ndarray:
        """X = H⁻¹ E for the unit columns E of ``keys`` (size, Σ dims)."""
        idx = np.concatenate([self._at[key] for key in keys])
        E = np.zeros((self._size, idx.size))
        E[idx, np.arange(idx.size)] = 1.0
        X = self._lu.solve(E)
        if not (np.all(np.isfinite(X)) and np.abs(self._H @ X - E).max() <= ACCURACY):
            raise np.linalg.LinAlgError("SystemCovariance: a solve is not accurate")
        return X

    def marginals(self, keys) -> list:
        """The marginal covariance of each of ``keys`` (its dimension square); those not asked before in one solve."""
        if self._ready(len(keys)):
            try:
                return self._solved_marginals(keys)
            except np.linalg.LinAlgError:
                self._failed = True
        return self._fallback.marginals(keys)

    def marginal(self, key) -> np.ndarray:
        return self.marginals([key])[0]

    def known(self) -> dict:
        """Key → every marginal answered so far (by the factored system or the solver)."""
        return {**self._fallback.known(), **(self._marginals if self._built else {})}

    def joint(self, keys) -> np.ndarray:
        """The joint marginal covariance of ``keys`` (distinct), in their order: the diagonal blocks are the
        marginals, the rest read off the columns of every key but the first. Those are kept for the latest
        ``KEPT`` keys, so joints that share their later keys (one landmark with each pose) cost one solve."""
        if self._ready(JOINT_COST):
            try:
                return self._solved_joint(list(keys))
            except np.linalg.LinAlgError:
                self._failed = True
        return self._fallback.joint(keys)

    def _solved_marginals(self, keys) -> list:
        missing = [key for key in dict.fromkeys(keys) if key not in self._marginals]
        for n in range(0, len(missing), CHUNK):  # (each solve's right-hand sides: size × dims × CHUNK floats)
            part = missing[n:n + CHUNK]
            X, column = self._solve(part), 0
            for key in part:
                idx = self._at[key]
                block = X[idx, column:column + idx.size]
                self._marginals[key] = 0.5 * (block + block.T)
                column += idx.size
        return [self._marginals[key] for key in keys]

    def _solved_joint(self, keys: list) -> np.ndarray:
        missing = [key for key in keys[1:] if key not in self._columns]
        if missing:
            X, column = self._solve(missing), 0
            for key in missing:
                self._columns[key] = X[:, column:column + self._at[key].size]
                column += self._at[key].size
        for key in keys[1:]:  # most recently used last
            self._columns[key] = self._columns.pop(key)
        while len(self._columns) > KEPT:
            del self._columns[next(iter(self._columns))]
        diagonal = self._solved_marginals(keys)
        blocks = [[None] * len(keys) for _ in keys]
        for a, key_a in enumerate(keys):
            blocks[a][a] = diagonal[a]
            for b in range(a + 1, len(keys)):
                blocks[a][b] = self._columns[keys[b]][self._at[key_a]]
                blocks[b][a] = blocks[a][b].T
        return np.block(blocks)


def block_marginals(solver, keys) -> list:
    """The marginal covariance of each of ``keys`` (distinct), cut from iSAM2's joint marginals of ``JOINT_CHUNK`` of
    them at a time: one joint of many variables costs about what a few of their marginals cost one by one (kitchen
    seed 0, the 331 poses of A-SLAM's smoother: 0.41 s against 3.2 s, of Dyn. SLAM's in chunks of 110: 0.28 s
    against 2.05 s; the same numbers to 1e-12). A windowed smoother's, one by one (:class:`SolverCovariance`)."""
    keys = list(keys)
    if solver.windowed:
        return SolverCovariance(solver).marginals(keys)
    out = []
    for n in range(0, len(keys), JOINT_CHUNK):
        part = keys[n:n + JOINT_CHUNK]
        joint = solver.joint(part)
        out.extend(joint[np.ix_(rows, rows)] for rows in slices([solver.estimate(key).size for key in part]))
    return out


def covariance_of(solver, expected: int = 0):
    """:class:`SystemCovariance` of a full smoother's current system (``solver``,
    :class:`~stslam.graph.solver.FullSolver`), factored at the first question if the caller ``expected`` at
    least ``BUILD_AFTER`` of them; :class:`SolverCovariance` of a windowed one (whose variables that left the
    window only it remembers)."""
    return SolverCovariance(solver) if solver.windowed else SystemCovariance(solver, expected)
