"""Cross-covariance between neighbours that fuse each other, tracked in factors (Luft, Schubert,
Roumeliotis and Burgard, "Recursive decentralized localization for multi-robot systems with
asynchronous pairwise communication", IJRR 2018), each vehicle computing only its own update. Pure.

**Anchors and factors.** The cross-covariance of vehicles a and b is carried through one random vector
both know of, the *anchor*: the error u (3,) of the broadcast pose that the pair's last fusion used,
at its epoch; U = cov(u) (3, 3) is that broadcast's covariance. Each vehicle keeps its factor, the
column block c = cov(e_self, u) (n, 3) of its own state's error against u, and

    cov(e_a, e_b) ~= c_a U^-1 c_b^T                                                       (1)

(Luft et al.'s sigma_ab sigma_ba^T with sigma = c U^-1/2): exact while the two errors are correlated
only through u. Each vehicle's own operations move its own factors as they move its covariance's
columns: a motion step c <- F c, an update with gain K and Jacobian H c <- c - K H c, a state added
(a zero row), marginalized (its row dropped) or decorrelated (its row zeroed).

**A fusion** (Luft et al.'s relative update, one-sided; vehicle.models.correlation_update computes it
and checks a claim before it is used): vehicle a fuses b's broadcast of epoch tau
(pose error e_bp, covariance U_b) with a measurement z = h(x_a, pose_b) + v. From (1) it has
C = cov(e_a, e_bp) (n, 3), and the joint prior [[P, C], [C^T, U_b]] gives the exact gain of a's rows,
K = (P H_a^T + C H_b^T) S^-1 with S = H_a P H_a^T + H_a C H_b^T + H_b C^T H_a^T + H_b U_b H_b^T + R.
a keeps x_a + K y and P - K S K^T; b is not changed (no vehicle takes an update another computed).
The pair's new anchor is u' = e_bp(tau): a's factor becomes

    c_a' = cov(e_a+, u') = C - K (H_a C + H_b U_b)                                          (2)

and b's is its *clone* of tau, cov(e_b, e_bp(tau)): a column block b starts at each broadcast epoch
(its own pose's columns of P at that instant) and keeps moving with its covariance. a's other factors
move by c <- c - K H_a c: the term -K H_b cov(e_bp, u_other) that correlations through third vehicles
would add is left out, as Luft et al. leave it out.

**Turns.** Two one-sided fusions of one pair from the same anchor at the same epoch would each miss
the other's, so each pair takes turns by epoch: at epoch k (of the broadcast period), the lower id of
the pair fuses the other's broadcast when k is even, the higher when it is odd (``fuser_at``).

**Claims.** What a vehicle tells a neighbour j with its broadcast of epoch tau (``Claim``): its anchor
for j (who fused, at which epoch) and its factor's pose rows cov(e_p(tau), u) (3, 3), and its
clones' pose rows cov(e_p(tau), e_p(e)) for the recent epochs e at which j had the turn, which j needs
where its own fusion set the anchor. ``resolve`` turns a claim and the receiver's own book into C and
the anchor the receiver's factor must follow, or refuses the claim (``ClaimRefused``: the pair's
correlation is then unknown, and the vehicle falls back to split CI for that neighbour).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

POSE = 3
CLONE_EPOCHS = 8  # own broadcasts whose clones are kept: a neighbour's turn comes every other epoch


def fuser_at(epoch_us: int, period_us: int, a: int, b: int) -> int:
    """Which of vehicles a and b fuses the other's broadcast of epoch ``epoch_us`` (module docstring)."""
    return min(a, b) if (epoch_us // period_us) % 2 == 0 else max(a, b)


class ClaimRefused(ValueError):
    """A neighbour's correlation claim that cannot be used: the reason names what was wrong."""


@dataclass(frozen=True)
class Anchor:
    """The anchor of a pair: ``fuser`` fused the other's broadcast of ``epoch_us``."""

    fuser: int
    epoch_us: int


@dataclass(frozen=True)
class Claim:
    """What vehicle ``sender`` says with its broadcast of ``epoch_us`` to one neighbour: its ``anchor``
    for the pair (None: neither has fused the other), its factor's pose rows ``rows`` (3, 3) =
    cov(e_p(epoch), u), and ``clones``: own broadcast epoch -> cov(e_p(epoch_us), e_p(that epoch)) (3, 3)."""

    sender: int
    epoch_us: int
    anchor: Anchor | None = None
    rows: np.ndarray | None = None
    clones: dict[int, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class Pair:
    """A vehicle's record of one neighbour: the pair's anchor and U = cov(u) (3, 3)."""

    anchor: Anchor
    U: np.ndarray


@dataclass(frozen=True)
class Resolved:
    """A claim resolved against the receiver's book: C = cov(e_self, e_their_pose(epoch)) (n, 3), the
    anchor the receiver's factor follows now (``adopt``: the clone of that epoch becomes its factor)."""

    C: np.ndarray
    adopt: Anchor | None = None


class Factors:
    """One vehicle's factors (n, 3) per neighbour and per clone of its recent broadcasts, as one array
    ``cols`` (n, 3 k) that moves with the covariance; the pairs' anchors; the pairs whose correlation is
    unknown (``broken``). Kept in the filter state (copied with it for replays)."""

    def __init__(self, n: int) -> None:
        self.cols = np.zeros((n, 0))
        self.slots: list[object] = []  # ("pair", id) or ("clone", epoch us) per 3 columns
        self.pairs: dict[int, Pair] = {}
        self.clone_cov: dict[int, np.ndarray] = {}  # epoch -> own broadcast pose covariance (3, 3)
        self.broken: set[int] = set()

    def copy(self) -> Factors:
        twin = Factors.__new__(Factors)
        twin.cols, twin.slots = self.cols.copy(), list(self.slots)
        twin.pairs, twin.clone_cov, twin.broken = dict(self.pairs), dict(self.clone_cov), set(self.broken)
        return twin

    # -- the columns, as the covariance changes ---------------------------------------------------

    def move(self, F: np.ndarray) -> None:
        """A motion step: c <- F c."""
        self.cols = F @ self.cols

    def gain(self, K: np.ndarray, H: np.ndarray) -> None:
        """An update with gain K (n, m) and Jacobian H (m, n): c <- c - K H c."""
        if self.cols.shape[1]:
            self.cols = self.cols - K @ (H @ self.cols)

    def grow(self, count: int) -> None:
        """``count`` states added after the last, uncorrelated with every anchor."""
        self.cols = np.vstack([self.cols, np.zeros((count, self.cols.shape[1]))])

    def drop(self, indices: list[int]) -> None:
        """The states at ``indices`` marginalized out."""
        self.cols = np.delete(self.cols, indices, axis=0)

    def decorrelate(self, indices: list[int]) -> None:
        """The states at ``indices`` made uncorrelated with everything (a spread reset)."""
        self.cols[indices, :] = 0.0

    # -- slots ------------------------------------------------------------------------------------

    def column(self, key: object) -> np.ndarray:
        """The factor (n, 3) under ``key`` (a view)."""
        at = 3 * self.slots.index(key)
        return self.cols[:, at : at + 3]

    def _put(self, key: object, block: np.ndarray) -> None:
        if key in self.slots:
            self.column(key)[:] = block
        else:
            self.slots.append(key)
            self.cols = np.hstack([self.cols, block])

    def _remove(self, key: object) -> None:
        if key in self.slots:
            at = 3 * self.slots.index(key)
            self.cols = np.delete(self.cols, np.s_[at : at + 3], axis=1)
            self.slots.remove(key)

    def start_clone(self, epoch_us: int, P: np.ndarray, U: np.ndarray, period_us: int) -> None:
        """The clone of this vehicle's broadcast of ``epoch_us``: cov(e, e_p) = P[:, :3], U its published
        covariance (3, 3); clones older than ``CLONE_EPOCHS`` periods are let go."""
        self._put(("clone", epoch_us), P[:, :POSE].copy())
        self.clone_cov[epoch_us] = U
        for old in [e for e in self.clone_cov if e <= epoch_us - CLONE_EPOCHS * period_us]:
            del self.clone_cov[old]
            self._remove(("clone", old))

    def set_pair(self, neighbour: int, anchor: Anchor, U: np.ndarray, column: np.ndarray) -> None:
        self.pairs[neighbour] = Pair(anchor, U)
        self._put(("pair", neighbour), column)

    def adopt(self, neighbour: int, anchor: Anchor) -> None:
        """The neighbour fused this vehicle's broadcast of ``anchor.epoch_us``: that clone becomes the factor."""
        self.set_pair(
            neighbour, anchor, self.clone_cov[anchor.epoch_us], self.column(("clone", anchor.epoch_us)).copy()
        )

    def break_pair(self, neighbour: int) -> None:
        """The pair's correlation is unknown from now on (split CI with that neighbour)."""
        self.broken.add(neighbour)
        self.pairs.pop(neighbour, None)
        self._remove(("pair", neighbour))

    def forget(self) -> None:
        """Every pair's correlation unknown (the state was replaced: a divergence fall-back)."""
        for neighbour in list(self.pairs) + list(self.broken):
            self.break_pair(neighbour)

    # -- what this vehicle claims -----------------------------------------------------------------

    def claim(self, own_id: int, neighbour: int, epoch_us: int, period_us: int) -> Claim:
        """The claim of this vehicle's broadcast of ``epoch_us`` to ``neighbour`` (module docstring)."""
        pair = self.pairs.get(neighbour)
        rows = None if pair is None else self.column(("pair", neighbour))[:POSE].copy()
        clones = {
            e: self.column(("clone", e))[:POSE].copy()
            for e in self.clone_cov
            if e < epoch_us and fuser_at(e, period_us, own_id, neighbour) == neighbour
        }
        return Claim(own_id, epoch_us, None if pair is None else pair.anchor, rows, clones)


def resolve(book: Factors, own_id: int, claim: Claim, their_cov: np.ndarray) -> Resolved:
    """C = cov(e_self, e_their_pose(claim.epoch_us)) (n, 3) from this vehicle's factors and the
    neighbour's ``claim`` (``their_cov`` (3, 3): the covariance of that broadcast), with the anchor this
    vehicle's factor must follow; ClaimRefused when the claim and the book cannot both be right, or
    something the claim needs is no longer kept."""
    j = claim.sender
    if j in book.broken:
        raise ClaimRefused(f"the correlation with {j} is unknown since an earlier claim failed")
    pair, told = book.pairs.get(j), claim.anchor
    if told is not None and told.fuser == j and (pair is None or told != pair.anchor):
        if told.epoch_us not in book.clone_cov:  # they fused ours: follow them, from our clone of that epoch
            raise ClaimRefused(f"{j} fused our broadcast of {told.epoch_us} us, whose clone is no longer kept")
        if pair is not None and pair.anchor.epoch_us >= told.epoch_us:
            raise ClaimRefused(f"{j} says it fused us at {told.epoch_us} us, not after our anchor {pair.anchor}")
        column, U = book.column(("clone", told.epoch_us)), book.clone_cov[told.epoch_us]
        return Resolved(_through(column, U, _rows(claim.rows, j)), told)
    if pair is None:
        if told is not None:
            raise ClaimRefused(f"{j} claims an anchor {told} this vehicle never had")
        return Resolved(np.zeros((book.cols.shape[0], POSE)))
    column = book.column(("pair", j))
    if pair.anchor.fuser == j:  # their fusion set the anchor and they say so
        return Resolved(_through(column, pair.U, _rows(claim.rows, j)))
    # ours set it (u: their broadcast of that epoch): their clone of it says how their pose follows u
    if told is not None and told.fuser == own_id and told.epoch_us > pair.anchor.epoch_us:
        raise ClaimRefused(f"{j} claims we fused it at {told.epoch_us} us, after our anchor {pair.anchor}")
    if told is not None and told.fuser == j:
        raise ClaimRefused(f"{j} claims its own anchor {told}, ours is {pair.anchor}")
    if claim.epoch_us == pair.anchor.epoch_us:
        rows = their_cov  # the same broadcast: cov(u, u)
    else:
        rows = _rows(claim.clones.get(pair.anchor.epoch_us), j)
    return Resolved(_through(column, pair.U, rows))


def _rows(rows: np.ndarray | None, sender: int) -> np.ndarray:
    if rows is None or np.shape(rows) != (POSE, POSE) or not np.all(np.isfinite(rows)):
        raise ClaimRefused(f"{sender}'s claim lacks the factor rows it needs")
    return np.asarray(rows, dtype=float)


def _through(column: np.ndarray, U: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Equation (1): c U^-1 r^T (n, 3)."""
    return column @ np.linalg.solve(U, rows.T)
