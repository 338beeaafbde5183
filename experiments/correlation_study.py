"""A linear study of what sharing cross-covariance factors (vehicle.models.correlation) is worth before
it is put through the processes (docs/decisions/cross-covariance.md). Pure and deterministic.

n vehicles, each a planar pose [x, y, yaw] as a random walk (process noise ``q`` per epoch), vehicle 1
with a GNSS fix every ``gnss_every`` epochs, the pairs of ``pairs`` measuring their relative position
z = p_b - p_a (noise ``relative_var`` per axis) at every epoch. Being linear, the true joint
covariance of the vehicles' errors under exactly the operations they perform can be followed beside
them (``Sigma``), so each method's honesty is its expected NEES tr(P^-1 Sigma_ii) (3 for a consistent
filter: no Monte Carlo needed) and its accuracy the RMS position error sqrt(tr Sigma_pp).

Methods: ``centralized`` (one joint Kalman filter fusing both directions of every pair at every
epoch); ``split-ci-both`` (each vehicle of a pair fuses the other's broadcast at every epoch by split
CI, as the vehicles do today); the others fuse a pair once per epoch, by the fuser whose turn it is
(correlation.fuser_at), one-sided: ``split-ci`` (the neighbour's estimate of unknown correlation),
``factors`` (the pair's cross-covariance from the factors, Kalman update; the fuser's other factors
moved by its own update c <- (I - K H) c), ``factors-luft`` (the same with Luft et al.'s map for the
other factors, c <- P+ P^-1 c), ``factors-residual-ci`` (the known part of the correlation taken out
exactly, split CI on what is left, e_b = C^T P^-1 e_a + r), and ``tree`` (factors on the edges of a
chain 1-2-...-n, split CI on the others); ``luft-two-sided`` is Luft et al.'s algorithm as published, both vehicles of
the pair updated by the one joint update (which the trust model here does not allow: it is measured to
see whether the one-sided form is what costs), sigma_ij sigma_ji^T with the reset sigma_ij = P_ij+,
sigma_ji = I and sigma_ik <- P_ii+ P_ii^-1 sigma_ik for the others. ``kia`` is Kia, Rounds and
Martinez's interim-master algorithm (IEEE Control Systems 2016), exact with cycles: every vehicle keeps
its own estimate and a copy of every pair's correlation factor sigma_jk (P_jk = Phi_j sigma_jk Phi_k^T,
Phi the product of a vehicle's own motion Jacobians, the identity for these random walks), and each
update (a relative measurement by the vehicle that made it, or vehicle 1's GNSS fix) is broadcast by
its maker to every vehicle of the swarm: the normalised residual S^-1/2 r and the gains' terms of the
two vehicles it measured; each vehicle l computes Gamma_j = (sigma_ja H_a^T + sigma_jb H_b^T) S^-1/2
for every vehicle, moves its own estimate by Phi_l Gamma_l S^-1/2 r and its covariance by
-Phi_l Gamma_l Gamma_l^T Phi_l^T, and every factor by sigma_jk <- sigma_jk - Gamma_j Gamma_k^T.
``Regime.loss``: each broadcast misses each vehicle with this probability (a vehicle that misses one
does not apply it: its estimate, covariance and copy of the factors stay as they were).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.models.cooperative import CooperativeRule
from vehicle.models.correlation import POSE, Anchor, Factors, fuser_at, resolve
from vehicle.models.correlation_update import pair_update

PERIOD_US = 200_000
H_POSITION = np.hstack([np.eye(2), np.zeros((2, 1))])
METHODS = (
    "centralized",
    "split-ci-both",
    "split-ci",
    "factors",
    "factors-luft",
    "factors-residual-ci",
    "tree",
    "luft-two-sided",
    "kia",
)


@dataclass(frozen=True)
class Regime:
    relative_var: float = 0.05  # m^2 per axis, the relative measurement's noise
    q: tuple[float, float, float] = (0.02, 0.02, 0.001)  # process noise per epoch [m^2, m^2, rad^2]
    prior: tuple[float, float, float] = (0.1, 0.1, 0.01)
    gnss_var: float = 0.5  # m^2 per axis, vehicle 1's fix
    gnss_every: int = 5  # epochs
    loss: float = 0.0  # ``kia``: the probability that a broadcast misses a vehicle
    seed: int = 0  # of the losses


@dataclass(frozen=True)
class Outcome:
    expected_nees: np.ndarray  # (n,) mean over the settled epochs of tr(P_i^-1 Sigma_ii)
    rms_position_m: float


def study(
    n: int,
    pairs: list[tuple[int, int]],
    method: str,
    regime: Regime = Regime(),
    *,
    epochs: int = 300,
    settle: int = 100,
) -> Outcome:
    """Run ``method`` (module docstring) on vehicles 0..n-1 ranging the ``pairs`` for ``epochs`` epochs;
    averaged after the first ``settle``."""
    if method == "centralized":
        return _centralized(n, pairs, regime, epochs, settle)
    if method == "luft-two-sided":
        return _two_sided(n, pairs, regime, epochs, settle)
    if method == "kia":
        return _interim_master(n, pairs, regime, epochs, settle)
    swarm = _Decentralized(n, regime, method)
    nees, spread = [], []
    for k in range(epochs):
        swarm.epoch(k, pairs)
        if k >= settle:
            nees.append(swarm.expected_nees())
            spread.append(swarm.position_spread())
    return Outcome(np.mean(nees, axis=0), float(np.sqrt(np.mean(spread))))


class _Decentralized:
    def __init__(self, n: int, regime: Regime, method: str) -> None:
        self.n, self.regime, self.method = n, regime, method
        self.P = [np.diag(regime.prior) for _ in range(n)]
        self.books = [Factors(POSE) for _ in range(n)]
        self.Sigma = np.kron(np.eye(n), np.diag(regime.prior))

    def _rows(self, i: int) -> slice:
        return slice(POSE * i, POSE * i + POSE)

    def epoch(self, k: int, pairs: list[tuple[int, int]]) -> None:
        t = k * PERIOD_US
        self.P = [P + np.diag(self.regime.q) for P in self.P]
        self.Sigma = self.Sigma + np.kron(np.eye(self.n), np.diag(self.regime.q))
        if k % self.regime.gnss_every == 0:
            self._gnss(0)
        for i in range(self.n):
            self.books[i].start_clone(t, self.P[i], self.P[i].copy(), PERIOD_US)
        claims = {
            (i, j): self.books[i].claim(i + 1, j + 1, t, PERIOD_US) for a, b in pairs for i, j in ((a, b), (b, a))
        }
        broadcast = [P.copy() for P in self.P]
        for a, b in pairs:
            fuser = fuser_at(t, PERIOD_US, a + 1, b + 1) - 1
            other = b if fuser == a else a
            self._fuse(fuser, other, claims[(other, fuser)], broadcast[other], exact=self._exact(a, b))
            if self.method == "split-ci-both":  # the other direction too, as the vehicles do today
                self._fuse(other, fuser, claims[(fuser, other)], broadcast[fuser], exact=False)

    def _exact(self, a: int, b: int) -> bool:
        return self.method not in ("split-ci", "split-ci-both") and (self.method != "tree" or abs(a - b) == 1)

    def _gnss(self, i: int) -> None:
        R = self.regime.gnss_var * np.eye(2)
        S = H_POSITION @ self.P[i] @ H_POSITION.T + R
        K = self.P[i] @ H_POSITION.T @ np.linalg.inv(S)
        self.P[i] = self.P[i] - K @ S @ K.T
        self.books[i].gain(K, H_POSITION)
        self._truth(i, None, K, H_POSITION, None, R)

    def _fuse(self, a: int, b: int, claim, U: np.ndarray, *, exact: bool) -> None:
        """a fuses b's broadcast (covariance U) with z = p_b - p_a."""
        H_own, H_their, R = -H_POSITION, H_POSITION, self.regime.relative_var * np.eye(2)
        book, P = self.books[a], self.P[a]
        C = np.zeros((POSE, POSE))
        if exact:
            resolved = resolve(book, a + 1, claim, U)
            if resolved.adopt is not None:
                book.adopt(b + 1, resolved.adopt)
            C = resolved.C
        if exact and self.method != "factors-residual-ci":
            update = pair_update(np.zeros(POSE), P, np.zeros(2), H_own, H_their, R, C, U)
            P_new, gain = update.P, update.K
        else:  # split CI, on the residual of what the factors explain (nothing for plain split CI)
            A = C.T @ np.linalg.inv(P)
            P_new, gain = split_ci(P, H_own + H_their @ A, R, H_their @ (U - C.T @ A.T) @ H_their.T)
        if self.method == "factors-luft":
            book.move(P_new @ np.linalg.inv(P))
        else:
            book.gain(gain, H_own)
        if exact:
            book.set_pair(b + 1, Anchor(a + 1, claim.epoch_us), U, C - gain @ (H_own @ C + H_their @ U))
        self.P[a] = P_new
        self._truth(a, b, gain, H_own, H_their, R)

    def _truth(self, a: int, b: int | None, K: np.ndarray, H_own: np.ndarray, H_their, R: np.ndarray) -> None:
        """Sigma after a's update e_a <- e_a - K (H_own e_a + H_their e_b) + K v."""
        seen, H = ([a], H_own) if b is None else ([a, b], np.hstack([H_own, H_their]))
        self.Sigma = truth_after(self.Sigma, [a], seen, K, H, R)

    def expected_nees(self) -> list[float]:
        return [
            float(np.trace(np.linalg.solve(self.P[i], self.Sigma[self._rows(i), self._rows(i)]))) for i in range(self.n)
        ]

    def position_spread(self) -> float:
        return float(np.mean([np.trace(self.Sigma[self._rows(i), self._rows(i)][:2, :2]) for i in range(self.n)]))


def rows_of(vehicles: list[int] | tuple[int, ...]) -> np.ndarray:
    """The rows of the joint error vector (3 n,) of ``vehicles``, in order."""
    return np.concatenate([np.arange(POSE * i, POSE * i + POSE) for i in vehicles])


def truth_after(Sigma: np.ndarray, updated, seen, K: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The true joint error covariance (3 n, 3 n) after the vehicles ``updated`` moved by gain K
    (3 len(updated), m) on a measurement H (m, 3 len(seen)) of the vehicles ``seen`` with noise R:
    e_updated <- e_updated - K H e_seen + K v."""
    L = np.eye(len(Sigma))
    L[np.ix_(rows_of(updated), rows_of(seen))] -= K @ H
    noise = np.zeros_like(Sigma)
    noise[np.ix_(rows_of(updated), rows_of(updated))] = K @ R @ K.T
    return L @ Sigma @ L.T + noise


def split_ci(P: np.ndarray, H: np.ndarray, R: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split CI of own estimate (P (n, n), seen through H (m, n)) and a measurement with independent noise
    R and a share S of unknown correlation, in measurement space with the weight of largest fused
    information, the vehicles' own rule (vehicle.models.cooperative.CooperativeRule): the new covariance
    and the gain K (n, m) of the mean (zero where the weight says the fix brings nothing)."""
    rule = CooperativeRule()
    M = H @ P @ H.T
    w = rule.choose_weight(M, R, S)
    if w >= 1.0:
        return P, np.zeros((len(P), len(R)))
    M_inv = np.linalg.inv(M)
    I_fix = rule.fix_information(R, S, np.array([w]))[0]
    M_new = np.linalg.inv(w * M_inv + I_fix)
    A = P @ H.T @ M_inv
    P_new = P + A @ (M_new - M) @ A.T
    return 0.5 * (P_new + P_new.T), A @ M_new @ I_fix


def _centralized(n: int, pairs: list[tuple[int, int]], regime: Regime, epochs: int, settle: int) -> Outcome:
    P = np.kron(np.eye(n), np.diag(regime.prior))
    spread = []

    def update(H: np.ndarray, R: np.ndarray) -> np.ndarray:
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        return P - K @ S @ K.T

    for k in range(epochs):
        P = P + np.kron(np.eye(n), np.diag(regime.q))
        if k % regime.gnss_every == 0:
            H = np.zeros((2, POSE * n))
            H[:, :POSE] = H_POSITION
            P = update(H, regime.gnss_var * np.eye(2))
        for a, b in pairs:
            for own, their in ((a, b), (b, a)):
                H = np.zeros((2, POSE * n))
                H[:, POSE * own : POSE * own + POSE] = -H_POSITION
                H[:, POSE * their : POSE * their + POSE] = H_POSITION
                P = update(H, regime.relative_var * np.eye(2))
        if k >= settle:
            spread.append(np.mean([np.trace(P[POSE * i : POSE * i + 2, POSE * i : POSE * i + 2]) for i in range(n)]))
    return Outcome(np.full(n, float(POSE)), float(np.sqrt(np.mean(spread))))


def _two_sided(n: int, pairs: list[tuple[int, int]], regime: Regime, epochs: int, settle: int) -> Outcome:
    """Luft et al. as published (module docstring): per ordered pair sigma[i][j] (3, 3)."""
    P = [np.diag(regime.prior) for _ in range(n)]
    sigma = {(i, j): np.zeros((POSE, POSE)) if i < j else np.eye(POSE) for i in range(n) for j in range(n) if i != j}
    Sigma = np.kron(np.eye(n), np.diag(regime.prior))
    nees, spread = [], []
    for k in range(epochs):
        P = [p + np.diag(regime.q) for p in P]
        Sigma = Sigma + np.kron(np.eye(n), np.diag(regime.q))
        updates = [((0,), H_POSITION, regime.gnss_var * np.eye(2))] if k % regime.gnss_every == 0 else []
        updates += [((a, b), np.hstack([-H_POSITION, H_POSITION]), regime.relative_var * np.eye(2)) for a, b in pairs]
        for who, H, R in updates:
            K = _joint_update(P, sigma, who, H, R, n)
            Sigma = truth_after(Sigma, who, who, K, H, R)
        if k >= settle:
            blocks = [Sigma[np.ix_(rows_of([i]), rows_of([i]))] for i in range(n)]
            nees.append([float(np.trace(np.linalg.solve(P[i], blocks[i]))) for i in range(n)])
            spread.append(np.mean([np.trace(b[:2, :2]) for b in blocks]))
    return Outcome(np.mean(nees, axis=0), float(np.sqrt(np.mean(spread))))


def _joint_update(P: list, sigma: dict, who: tuple[int, ...], H: np.ndarray, R: np.ndarray, n: int) -> np.ndarray:
    """One update of the vehicles ``who`` (one, or the pair) by the joint Kalman update of their prior
    (the pair's cross-covariance sigma_ab sigma_ba^T); P, sigma changed in place (reset sigma_ab = P_ab+,
    sigma_ba = I; the others sigma_ik <- P_ii+ P_ii^-1 sigma_ik). Returns the gain K (3 len(who), m)."""
    if len(who) == 1:
        J = P[who[0]]
    else:
        cross = sigma[who] @ sigma[who[::-1]].T
        J = np.block([[P[who[0]], cross], [cross.T, P[who[1]]]])
    S = H @ J @ H.T + R
    K = J @ H.T @ np.linalg.inv(S)
    J_new = J - K @ S @ K.T
    for slot, i in enumerate(who):
        block = J_new[POSE * slot : POSE * slot + POSE, POSE * slot : POSE * slot + POSE]
        M = block @ np.linalg.inv(P[i])
        for j in range(n):
            if j not in who:
                sigma[(i, j)] = M @ sigma[(i, j)]
        P[i] = block
    if len(who) == 2:
        sigma[who], sigma[who[::-1]] = J_new[:POSE, POSE:], np.eye(POSE)
    return K


@dataclass(frozen=True)
class KiaOutcome(Outcome):
    """An ``Outcome`` of ``kia`` (over the settled epochs before it broke down, NaN when it broke down
    before), with the largest difference between any vehicle's covariance and the centralized
    filter's block for it (0 to rounding when no broadcast is lost), the broadcasts each vehicle
    receives per epoch (each update goes to the n - 1 others), and the epoch at which a vehicle's
    books stopped describing a possible joint covariance (an update's S or a vehicle's covariance not
    positive definite; None: it did not)."""

    largest_gap: float = 0.0
    messages_per_epoch: float = 0.0
    broke_at: int | None = None


def _interim_master(n: int, pairs: list[tuple[int, int]], regime: Regime, epochs: int, settle: int) -> KiaOutcome:
    """Kia et al.'s algorithm (module docstring) beside the centralized filter and the truth."""
    rng = np.random.default_rng(regime.seed)
    Q, prior = np.diag(regime.q), np.diag(regime.prior)
    P = [prior.copy() for _ in range(n)]  # each vehicle's own covariance
    books = [{(j, k): np.zeros((POSE, POSE)) for j in range(n) for k in range(n) if j != k} for _ in range(n)]
    central = np.kron(np.eye(n), prior)
    Sigma = central.copy()
    nees, spread, gap, sent, broke_at = [], [], 0.0, 0, None
    for k in range(epochs):
        P = [p + Q for p in P]  # Phi = I: the factors stay, P_jk = sigma_jk
        central = central + np.kron(np.eye(n), Q)
        Sigma = Sigma + np.kron(np.eye(n), Q)
        updates = [((0,), (H_POSITION,), regime.gnss_var)] if k % regime.gnss_every == 0 else []
        updates += [
            ((own, their), (-H_POSITION, H_POSITION), regime.relative_var)
            for a, b in pairs
            for own, their in ((a, b), (b, a))
        ]
        for who, Hs, var in updates:
            R = var * np.eye(2)
            S = _innovation_cov(P, books[who[0]], who, Hs, R)
            if not _positive(S):
                broke_at = k
                break
            heard = [v for v in range(n) if v == who[0] or rng.random() >= regime.loss]
            sent += n - 1
            gains = _broadcast_update(P, books, heard, who, Hs, _inverse_root(S))
            central = _joint_kalman(central, who, Hs, R, n)
            Sigma = truth_after(Sigma, heard, list(who), np.vstack(gains), np.hstack(Hs), R)
        if broke_at is None and not all(_positive(p) for p in P):
            broke_at = k
        if broke_at is not None:
            break
        gap = max(gap, max(float(np.abs(P[i] - central[_block(i), _block(i)]).max()) for i in range(n)))
        if k >= settle:
            blocks = [Sigma[_block(i), _block(i)] for i in range(n)]
            nees.append([float(np.trace(np.linalg.solve(P[i], blocks[i]))) for i in range(n)])
            spread.append(np.mean([np.trace(b[:2, :2]) for b in blocks]))
    mean_nees = np.mean(nees, axis=0) if nees else np.full(n, np.nan)
    rms = float(np.sqrt(np.mean(spread))) if spread else float("nan")
    return KiaOutcome(mean_nees, rms, gap, sent / (k + 1) / n, broke_at)


def _broadcast_update(P: list, books: list, heard: list[int], who, Hs, S_root_inv: np.ndarray) -> list[np.ndarray]:
    """One update as the vehicles ``heard`` apply its broadcast (module docstring), P and books changed
    in place: each computes every Gamma_j from its copy of the factors and the covariances before the
    update. Returns their gains K_v = Gamma_v S^-1/2 (3, m), in the order of ``heard``."""
    before, gains = list(P), []
    for v in heard:
        gammas = {j: _gamma(before, books[v], j, who, Hs) @ S_root_inv for j in range(len(P))}
        gains.append(gammas[v] @ S_root_inv)
        P[v] = P[v] - gammas[v] @ gammas[v].T
        for (j, m), factor in books[v].items():
            books[v][(j, m)] = factor - gammas[j] @ gammas[m].T
    return gains


def _positive(A: np.ndarray) -> bool:
    return bool(np.linalg.eigvalsh(0.5 * (A + A.T)).min() > 0.0)


def _block(i: int) -> slice:
    return slice(POSE * i, POSE * i + POSE)


def _cross(P: list, book: dict, j: int, m: int) -> np.ndarray:
    """cov(e_j, e_m) as a vehicle's book has it (its own P on the diagonal)."""
    return P[j] if j == m else book[(j, m)]


def _innovation_cov(P: list, book: dict, who, Hs, R: np.ndarray) -> np.ndarray:
    """S of an update of the vehicles ``who`` seen through ``Hs``, from the maker's book."""
    S = R.copy()
    for a, H_a in zip(who, Hs):
        for b, H_b in zip(who, Hs):
            S = S + H_a @ _cross(P, book, a, b) @ H_b.T
    return S


def _gamma(P: list, book: dict, j: int, who, Hs) -> np.ndarray:
    """sum over the measured vehicles a of cov(e_j, e_a) H_a^T (3, m), from a book: the measured
    vehicles' own rows are the maker's broadcast (it alone knows them: its own P, and the measured
    neighbour's broadcast P), a third vehicle's the book's factors."""
    return sum(_cross(P, book, j, a) @ H_a.T for a, H_a in zip(who, Hs))


def _inverse_root(S: np.ndarray) -> np.ndarray:
    """S^-1/2 (symmetric)."""
    values, vectors = np.linalg.eigh(S)
    return (vectors / np.sqrt(values)) @ vectors.T


def _joint_kalman(P: np.ndarray, who, Hs, R: np.ndarray, n: int) -> np.ndarray:
    H = np.zeros((2, POSE * n))
    for a, H_a in zip(who, Hs):
        H[:, _block(a)] = H_a
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return P - K @ S @ K.T
