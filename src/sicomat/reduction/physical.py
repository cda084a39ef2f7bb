"""Physical regrouping (paper III.C.3): a smaller lumped model that keeps named degrees of freedom.

The kept bodies are named by the user, chosen by a technological rule (the bodies carrying
actuators, their reactions, sensors, their references, and the tool) or found by merging, one at a
time, the two groups of bodies joined by the stiffest spring (highest ``√(k (1/m_a + 1/m_b))``)
until the requested order, or the band of interest, is reached.

Every other body is then eliminated by static condensation onto the kept ones (Guyan): springs in
series combine as ``1/k = Σ 1/k_i``, in parallel as ``Σ k_i``, through any topology and
transmission ratio, and the stiffness matrix of the kept bodies is exact at 0 Hz. A removed body's
mass goes to the kept bodies in proportion to how it follows them statically (the lever rule; all
of it to a body it is rigidly tied to), reflected through the ratios so that the kinetic energy of
the rigid-body motion — the total moving mass — is unchanged. Dampers follow the same projection,
frictions (viscous and Coulomb) are mapped element by element. The result is a new
:class:`~sicomat.description.mechanics.LumpedSpec`: physical parameters, the same actuator and sensor names, ready
to be saved in a model file with :func:`reduced_machine`.
"""

from __future__ import annotations

import heapq
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

import numpy as np
import scipy.linalg

from ..errors import ModelError
from ..mechanics.lumped import Mechanics, build_mechanics
from ..description.mechanics import GROUND, LumpedSpec
from ..description.registry import MechanicsKind, registered_types

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine, MechanicsSpec
    from .error import ReductionResult

__all__ = ["physical_reduction", "technological_dofs", "reduced_machine"]

_UNIT_TOL = 1e-6  # how close to ±1 an actuator's or sensor's weight on a kept body must be


# --------------------------------------------------------------------------- choosing the kept dofs
def technological_dofs(spec: "MechanicsSpec", tool: str | None = None) -> tuple[str, ...]:
    """The bodies a technological analysis keeps, in file order.

    The bodies of the actuators and their reactions, the bodies of the sensors and the bodies
    they measure relative to, and the tool (the load point) when given.

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> technological_dofs(ChainSpec(type="chain", masses=[1, 1, 1, 1], stiffnesses=[1, 1, 1]))
    ('m1', 'm4')
    """
    lumped = spec.to_lumped()
    marked = set(_signal_priority(lumped, tool))
    return tuple(name for name in lumped.bodies if name in marked)


def _signal_priority(lumped: LumpedSpec, tool: str | None) -> dict[str, int]:
    """0: carries an actuator or a sensor; 1: the tool; 2: a reaction or a sensor reference."""
    rank: dict[str, int] = {}

    def mark(body: str | None, level: int) -> None:
        if body is not None:
            rank[body] = min(rank.get(body, level), level)

    for act in lumped.actuators.values():
        mark(act.body, 0)
        mark(act.reaction, 2)
    for sensor in lumped.sensors.values():
        mark(sensor.body, 0)
        mark(sensor.relative_to, 2)
    if tool is not None:
        mark(tool, 1)
    return rank


def _reference_shape(mech: Mechanics) -> np.ndarray:
    """The rigid motion of each group of bodies linked to each other (ground links ignored).

    Gives the transmission ratios between bodies: ``ψ_i / ψ_a`` is how far body ``i`` moves when
    body ``a`` moves one unit with the links between bodies unstretched. Propagated along the
    links (so unit ratios give exactly 1); 1 for a group whose ratios contradict each other.
    """
    n = mech.n
    links = [link.g for link in (*mech.couplings, *mech.frictions) if np.count_nonzero(link.g) == 2]
    neighbours: dict[int, list[tuple[int, float]]] = {i: [] for i in range(n)}
    for g in links:
        a, b = (int(i) for i in np.flatnonzero(g))
        neighbours[a].append((b, -g[a] / g[b]))  # r_a q_a = r_b q_b with g_a = r_a, g_b = -r_b
        neighbours[b].append((a, -g[b] / g[a]))
    psi = np.full(n, np.nan)
    for start in range(n):
        if not np.isnan(psi[start]):
            continue
        psi[start] = 1.0
        members, stack = [start], [start]
        while stack:
            a = stack.pop()
            for b, ratio in neighbours[a]:
                if np.isnan(psi[b]):
                    psi[b] = psi[a] * ratio
                    members.append(b)
                    stack.append(b)
        consistent = all(abs(psi[b] - psi[a] * ratio) <= 1e-9 * abs(psi[b])
                         for a in members for b, ratio in neighbours[a])
        if not consistent:
            psi[members] = 1.0
    return psi


def _greedy_keep(lumped: LumpedSpec, mech: Mechanics, psi: np.ndarray, *, bodies_wanted: int | None,
                 omega_stop: float | None, tool: str | None) -> list[str]:
    """Merge the groups joined by the stiffest spring until the count or the band is reached."""
    names = mech.dof_names
    n = mech.n
    mass = mech.lumped_masses("physical regrouping") * psi ** 2  # in the normalised coordinates q = ψ p
    springs = []  # (a, b or -1 for the ground, normalised stiffness)
    for link in mech.couplings:
        if link.stiffness <= 0:
            continue
        ends = np.flatnonzero(link.g)
        gh = link.g[ends] * psi[ends]
        if len(ends) == 2:
            springs.append((int(ends[0]), int(ends[1]), link.stiffness * abs(gh[0] * gh[1])))
        else:
            springs.append((int(ends[0]), -1, link.stiffness * gh[0] ** 2))
    priority = _signal_priority(lumped, tool)
    signal = {names.index(b) for b in priority}
    group = list(range(n))  # group id per body (a body index); -1: merged into the ground
    gmass = {i: float(mass[i]) for i in range(n)}
    gsignal = {i: i in signal for i in range(n)}
    adj: dict[int, dict[int, float]] = {i: {} for i in range(n)}  # aggregated (parallel) stiffness
    for a, b, k in springs:
        if a == b:
            continue
        adj[a][b] = adj[a].get(b, 0.0) + k
        if b != -1:
            adj[b][a] = adj[b].get(a, 0.0) + k
    version = {i: 0 for i in range(n)}
    heap: list[tuple[float, int, int, int, int]] = []

    def push(g: int, h: int) -> None:
        k = adj[g][h]
        if h == -1:
            if gsignal[g]:
                return  # a body carrying a signal never disappears into the frame
            w = np.sqrt(k / gmass[g])
        else:
            w = np.sqrt(k * (1.0 / gmass[g] + 1.0 / gmass[h]))
        heapq.heappush(heap, (-w, g, h, version[g], version.get(h, 0)))

    for g in range(n):
        for h in adj[g]:
            if h == -1 or g < h:
                push(g, h)
    alive = n
    while True:
        if bodies_wanted is not None and alive <= bodies_wanted:
            break
        best = None
        while heap:
            negw, g, h, vg, vh = heapq.heappop(heap)
            if g in version and version[g] == vg and (h == -1 or (h in version and version[h] == vh)):
                best = (-negw, g, h)
                break
        if best is None:
            if bodies_wanted is not None:
                raise ModelError(f"cannot regroup into {bodies_wanted} bodies: the remaining {alive} "
                                 "groups of bodies are joined by no spring (only friction or actuators); "
                                 "name the bodies to keep instead", path="order", value=2 * bodies_wanted)
            break
        w, g, h = best
        if omega_stop is not None and bodies_wanted is None and w < omega_stop:
            break
        if h == -1:  # g joins the frame
            for m, k in adj.pop(g).items():
                if m != -1:
                    adj[m].pop(g)
                    adj[m][-1] = adj[m].get(-1, 0.0) + k
                    version[m] += 1
                    for x in adj[m]:
                        push(m, x)
            del version[g]
            group = [-1 if x == g else x for x in group]
        else:  # h joins g
            gmass[g] += gmass.pop(h)
            gsignal[g] = gsignal[g] or gsignal.pop(h)
            for m, k in adj.pop(h).items():
                if m == g:
                    continue
                adj[g][m] = adj[g].get(m, 0.0) + k
                if m != -1:
                    adj[m].pop(h)
                    adj[m][g] = adj[m].get(g, 0.0) + k
            adj[g].pop(h, None)
            del version[h]
            version[g] += 1
            for m in adj[g]:
                push(g, m)
            group = [g if x == h else x for x in group]
        alive -= 1

    kept = []
    for g in sorted({g for g in group if g != -1}):
        members = [i for i in range(n) if group[i] == g]
        kept.append(_representative(members, names, priority, mass, springs))
    return [name for name in names if name in kept]


def _representative(members: list[int], names: Sequence[str], priority: Mapping[str, int],
                    mass: np.ndarray, springs) -> str:
    """The body that names a group: best technological rank, then the compliance-weighted centre."""
    if len(members) == 1:
        return names[members[0]]
    best_rank = min(priority.get(names[i], 3) for i in members)
    candidates = [i for i in members if priority.get(names[i], 3) == best_rank]
    if len(candidates) == 1:
        return names[candidates[0]]
    local = {i: k for k, i in enumerate(members)}
    L = np.zeros((len(members), len(members)))
    for a, b, k in springs:
        if a in local and b in local:
            ia, ib = local[a], local[b]
            L[ia, ia] += k
            L[ib, ib] += k
            L[ia, ib] -= k
            L[ib, ia] -= k
    Lp = np.linalg.pinv(L)
    d = np.diag(Lp)
    R = d[:, None] + d[None, :] - 2 * Lp  # compliance between bodies of the group
    m = mass[members]
    cost = {i: float(R[local[i]] @ m) for i in candidates}
    return names[min(candidates, key=lambda i: (cost[i], -mass[i]))]


# --------------------------------------------------------------------------- condensation
def _condensation(mech: Mechanics, kept_idx: list[int]) -> np.ndarray:
    """``T`` (n, n_kept): the static motion of every body for unit motions of the kept ones."""
    n = mech.n
    removed = [i for i in range(n) if i not in kept_idx]
    T = np.zeros((n, len(kept_idx)))
    T[kept_idx, np.arange(len(kept_idx))] = 1.0
    if not removed:
        return T
    springs = [link.g for link in mech.couplings if link.stiffness > 0]
    held = np.vstack(springs)[:, removed] if springs else np.zeros((1, len(removed)))
    free = scipy.linalg.null_space(held, rcond=1e-10)
    if free.shape[1]:
        loose = [mech.dof_names[removed[i]] for i in np.flatnonzero(np.max(np.abs(free), axis=1) > 1e-8)]
        raise ModelError(f"cannot merge {', '.join(repr(b) for b in loose)}: no spring holds "
                         f"{'it' if len(loose) == 1 else 'them'} to a kept body or to the frame "
                         "(only friction, actuators or nothing), so the kept bodies do not determine "
                         f"{'its' if len(loose) == 1 else 'their'} motion; keep one of them",
                         path="keep", value=loose)
    K = mech.stiffness
    Koo = K[np.ix_(removed, removed)]
    Kok = K[np.ix_(removed, kept_idx)]
    d = 1.0 / np.sqrt(np.diag(Koo))
    X = scipy.linalg.solve(Koo * np.outer(d, d), -Kok * d[:, None], assume_a="pos") * d[:, None]
    T[removed] = X
    return T


def _ratios(a: str, b: str, psi: Mapping[str, float], kinds: Mapping[str, str]) -> tuple[float, list[float]]:
    """Scale ``λ`` and the ratios ``[λ/ψ_a, λ/ψ_b]`` of a link on the normalised stretch ``p_a − p_b``.

    ``λ`` is the ψ of a translational end when there is one, so that end's ratio is 1 and the link
    stretches in metres (the model file's default), else the ψ of the first end.
    """
    if b != GROUND and kinds[b] == "translational" and kinds[a] != "translational":
        lam = psi[b]
    else:
        lam = psi[a]
    return lam, [lam / psi[a], 1.0 if b == GROUND else lam / psi[b]]


def _pieces(gh: np.ndarray) -> list[tuple[int, int, float]]:
    """Split a normalised stretch vector into two-ended (``b ≥ 0``) or grounded (``b = -1``) pieces."""
    pos = {i: float(v) for i, v in enumerate(gh) if v > 0}
    neg = {i: float(-v) for i, v in enumerate(gh) if v < 0}
    out = []
    while pos and neg:
        a = max(pos, key=pos.__getitem__)
        b = max(neg, key=neg.__getitem__)
        c = min(pos[a], neg[b])
        out.append((a, b, c))
        for side, key in ((pos, a), (neg, b)):
            side[key] -= c
            if side[key] <= 1e-12 * c:
                del side[key]
    out += [(i, -1, c) for i, c in (*pos.items(), *neg.items())]
    return out


def _tidy(value):
    """Round to 12 significant digits: the condensation's round-off stays out of model files."""
    if isinstance(value, (list, tuple)):
        return [_tidy(v) for v in value]
    return float(f"{float(value):.12g}")


def _unique(name: str, taken: set[str]) -> str:
    out, k = name, 2
    while out in taken:
        out, k = f"{name}-{k}", k + 1
    taken.add(out)
    return out


def _single_target(w: np.ndarray, kept: Sequence[str], what: str) -> tuple[str | None, str | None]:
    """``(plus, minus)``: the kept bodies of a weight vector that must read ``e_plus − e_minus``."""
    w = np.where(np.abs(w) <= _UNIT_TOL, 0.0, w)
    plus = [int(i) for i in np.flatnonzero(w) if abs(w[i] - 1.0) <= _UNIT_TOL]
    minus = [int(i) for i in np.flatnonzero(w) if abs(w[i] + 1.0) <= _UNIT_TOL]
    if np.count_nonzero(w) != len(plus) + len(minus) or len(plus) > 1 or len(minus) > 1 or \
            (minus and not plus):
        spread = ", ".join(f"{kept[int(i)]}: {w[i]:.4g}" for i in np.flatnonzero(w))
        raise ModelError(f"{what} would act on several kept bodies or through a ratio after merging "
                         f"({spread or 'on none'}); keep its body (an actuator or sensor reads or "
                         "drives one body, relative to at most one other, with unit ratio)",
                         path="keep", value=list(kept))
    return (kept[plus[0]] if plus else None), (kept[minus[0]] if minus else None)


def physical_reduction(spec: "MechanicsSpec", keep: Iterable[str] | None = None, *, order: int | None = None,
                       band_hz: tuple[float, float] | None = None, tool: str | None = None,
                       margin: float = 10.0, inputs: Sequence[str] | None = None,
                       outputs: Sequence[str] | None = None) -> "ReductionResult":
    """Regroup a lumped model onto a few of its bodies (paper III.C.3).

    Parameters
    ----------
    spec : LumpedSpec, ChainSpec or BeltRackSpec
        The full mechanics description (an axis's ``mechanics``).
    keep : iterable of str, optional
        The bodies to keep. When not given: with ``order``, merge along the stiffest springs until
        ``order / 2`` bodies are left; with ``band_hz`` only, merge while the stiffest spring's
        frequency exceeds ``margin`` times the band's upper limit; with neither, keep
        :func:`technological_dofs`. Each group is named after its body carrying an actuator or a
        sensor, else the tool, else a reaction or reference, else its compliance-weighted centre.
    order : int, optional
        Number of states wanted (two per kept body).
    band_hz : (float, float), optional
        Band of interest (Hz): the stop rule above, and the reported band errors.
    tool : str, optional
        The axis's tool (load) body, kept by the technological rule.
    margin : float, optional
        How much stiffer than the band a spring must be to be merged (frequency ratio).
    inputs, outputs : sequence of str, optional
        The transfer the error figures compare (actuator and sensor names, see
        :func:`~sicomat.reduction.error.select_transfer`); all of them by default. The regrouping
        itself depends only on the mechanics.

    Returns
    -------
    ReductionResult
        ``spec`` (the new :class:`~sicomat.description.mechanics.LumpedSpec`), ``mechanics``, ``kept`` and
        ``merged_into``; the plants are the mechanics' state spaces from ``inputs`` to
        ``outputs`` (same actuator and sensor names).

    Raises
    ------
    ModelError
        Empty keep-list, unknown body names, an odd or out-of-range order, a body that no spring
        holds to the kept ones, or an actuator/sensor that the kept bodies cannot carry.

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> chain = ChainSpec(type="chain", masses=[1, 2, 3], stiffnesses=[1e9, 1e3])
    >>> res = physical_reduction(chain, keep=["m1", "m3"])
    >>> round(res.spec.bodies["m1"].mass, 4), round(res.spec.bodies["m3"].mass, 4)  # m2 rides on m1
    (3.0, 3.0)
    """
    from .error import ReductionResult, check_band, select_transfer
    from .modal import check_order

    band_hz = check_band(band_hz)
    if isinstance(spec, Mechanics) or not isinstance(spec, MechanicsKind):
        raise TypeError("physical_reduction takes a mechanics description (a registered type: "
                        f"{', '.join(registered_types('mechanics'))}; e.g. axis.mechanics), not {type(spec).__name__}")
    lumped = spec.to_lumped()
    mech = build_mechanics(lumped)
    full = select_transfer(mech.state_space(), inputs, outputs)
    names = mech.dof_names
    n = mech.n
    if tool is not None and tool not in names:
        raise ModelError(f"unknown tool body; expected one of {', '.join(names)}", path="tool", value=tool)
    if order is not None:
        check_order(order, 2 * n, 0, what="model")
        if order % 2:
            raise ModelError("physical regrouping keeps whole bodies: expected an even order (two states "
                             "per body)", path="order", value=order)
    psi = _reference_shape(mech)
    if keep is not None:
        keep = [keep] if isinstance(keep, str) else list(keep)
        if not keep:
            raise ModelError(f"the keep-list is empty; expected body names among {', '.join(names)}",
                             path="keep", value=keep)
        unknown = [k for k in keep if k not in names]
        if unknown:
            raise ModelError(f"unknown bod{'y' if len(unknown) == 1 else 'ies'} "
                             f"{', '.join(repr(u) for u in unknown)}; expected names among {', '.join(names)}",
                             path="keep", value=unknown if len(unknown) > 1 else unknown[0])
        if order is not None and order != 2 * len(set(keep)):
            raise ModelError(f"the order ({order}) and the keep-list ({len(set(keep))} bodies, "
                             f"{2 * len(set(keep))} states) disagree", path="order", value=order)
        kept = [name for name in names if name in set(keep)]
    elif order is not None or band_hz is not None:
        kept = _greedy_keep(lumped, mech, psi, bodies_wanted=None if order is None else order // 2,
                            omega_stop=None if band_hz is None else margin * 2 * np.pi * band_hz[1], tool=tool)
    else:
        kept = list(technological_dofs(lumped, tool))
        if not kept:
            raise ModelError("the mechanics has no actuator, sensor or tool to keep; name the bodies to "
                             "keep or give an order", path="keep")

    kept_idx = [names.index(k) for k in kept]
    T = _condensation(mech, kept_idx)
    new_spec, notes, merged_into = _regrouped_spec(lumped, mech, kept, kept_idx, T, psi)
    red_mech = build_mechanics(new_spec)
    return ReductionResult(method="physical", variant="regrouping", full=full,
                           reduced=red_mech.state_space().select(full.inputs, full.outputs), band_hz=band_hz,
                           kept=tuple(kept),
                           mechanics=red_mech, spec=new_spec, notes=tuple(notes), merged_into=merged_into)


def _regrouped_spec(lumped: LumpedSpec, mech: Mechanics, kept: list[str], kept_idx: list[int],
                    T: np.ndarray, psi_all: np.ndarray):
    names = mech.dof_names
    kinds = {d.name: d.kind for d in mech.dofs}
    psi = {names[i]: float(psi_all[i]) for i in range(mech.n)}
    psi_k = psi_all[kept_idx]
    notes: list[str] = []
    nk = len(kept)

    # masses: each body's share, reflected through the ratios (rigid-motion kinetic energy kept)
    m = mech.lumped_masses("physical regrouping")
    share = T * psi_k[None, :] / psi_all[:, None]  # how far body i follows kept body a, normalised
    masses = (m[:, None] * T * psi_all[:, None] / psi_k[None, :]).sum(axis=0)  # Σ m_i T_ia ψ_i/ψ_a
    merged_into = {}
    for i in range(mech.n):
        if i not in kept_idx:
            merged_into[names[i]] = kept[int(np.argmax(np.abs(share[i])))] if np.any(share[i]) else GROUND
    if np.any(masses <= 0):
        raise ModelError("the regrouped masses are not all positive; choose other bodies to keep",
                         path="keep", value=kept)

    # springs and their dampers: condensed matrices, split into two-ended elements
    K = mech.stiffness
    removed = [i for i in range(mech.n) if i not in kept_idx]
    Kr = K[np.ix_(kept_idx, kept_idx)] + K[np.ix_(kept_idx, removed)] @ T[removed]
    Dc = np.zeros((mech.n, mech.n))
    for link in mech.couplings:
        Dc += link.damping * np.outer(link.g, link.g)
    Dr = T.T @ Dc @ T
    S = np.outer(psi_k, psi_k)
    Kh, Dh = Kr * S, Dr * S
    projected = [(link, psi_k * (T.T @ link.g)) for link in mech.couplings]
    couplings: dict[str, dict[str, Any]] = {}
    taken: set[str] = set()

    def contributors(a: int, b: int | None) -> list[str]:
        out = []
        for link, gh in projected:
            support = np.abs(gh) > 1e-9 * max(np.max(np.abs(gh)), 1e-300)
            if b is None:
                if support[a] and abs(gh.sum()) > 1e-9 * np.max(np.abs(gh)):
                    out.append(link.name)
            elif support[a] and support[b]:
                out.append(link.name)
        return out

    def add(a: int, b: int | None, k: float, c: float) -> None:
        ka, kb = kept[a], (GROUND if b is None else kept[b])
        who = contributors(a, b)
        base = who[0] if len(who) == 1 else f"{ka}-{kb}"
        lam, ratios = _ratios(ka, kb, psi, kinds)
        couplings[_unique(base, taken)] = {"between": [ka, kb], "ratios": _tidy(ratios),
                                           "stiffness": _tidy(k / lam ** 2), "damping": _tidy(c / lam ** 2)}

    def clean(value: float, scale: float, what: str) -> float:
        # round-off of the condensation is relative to the springs attached to the kept bodies
        if value < -1e-8 * scale:
            notes.append(f"{what} came out negative ({value:.4g}) and was dropped")
        return value if value > 1e-9 * scale else 0.0

    k_ref = np.diag(K)[kept_idx] * psi_k ** 2  # every spring attached to a kept body, before condensing
    c_ref = np.diag(Dc)[kept_idx] * psi_k ** 2
    for a in range(nk):
        for b in range(a + 1, nk):
            k = clean(-Kh[a, b], np.sqrt(k_ref[a] * k_ref[b]), f"the stiffness between {kept[a]} and {kept[b]}")
            c = clean(-Dh[a, b], np.sqrt(c_ref[a] * c_ref[b]), f"the damping between {kept[a]} and {kept[b]}")
            if k > 0 or c > 0:
                add(a, b, k, c)
    for a in range(nk):
        k = clean(Kh[a].sum(), k_ref[a], f"the stiffness from {kept[a]} to the frame")
        c = clean(Dh[a].sum(), c_ref[a], f"the damping from {kept[a]} to the frame")
        if k > 0 or c > 0:
            add(a, None, k, c)

    # frictions, element by element (they carry Coulomb forces); pieces on the same pair add up
    pieces_by_pair: dict[tuple[int, int], list[tuple[str, float, float, float]]] = {}
    shared, dropped = [], []
    for link in mech.frictions:
        gh = psi_k * (T.T @ link.g)
        scale = float(np.max(np.abs(link.g * psi_all)))
        gh = np.where(np.abs(gh) <= 1e-9 * scale, 0.0, gh)
        if not np.any(gh):
            dropped.append(link.name)
            continue
        pieces = _pieces(gh)
        total = sum(c for _, _, c in pieces)
        if len(pieces) > 1:
            shared.append(link.name)
        for a, b, c in pieces:  # viscous by row sums (rigid-motion dissipation kept), forces by share
            pieces_by_pair.setdefault((a, b), []).append(
                (link.name, link.damping * c * total, link.coulomb * c, link.static * c))
    frictions: dict[str, dict[str, Any]] = {}
    ftaken: set[str] = set()
    for (a, b), items in pieces_by_pair.items():
        ka, kb = kept[a], (GROUND if b < 0 else kept[b])
        lam, ratios = _ratios(ka, kb, psi, kinds)
        origin = {item[0] for item in items}
        base = items[0][0] if len(origin) == 1 and items[0][0] not in ftaken else f"{ka}-{kb}"
        viscous = sum(i[1] for i in items) / lam ** 2
        coulomb = sum(i[2] for i in items) / abs(lam)
        static = sum(i[3] for i in items) / abs(lam)
        entry = {"between": [ka, kb], "ratios": _tidy(ratios), "viscous": _tidy(viscous),
                 "coulomb": _tidy(coulomb)}
        if static > coulomb * (1 + 1e-12):
            entry["static"] = max(_tidy(static), entry["coulomb"])
        frictions[_unique(base, ftaken)] = entry
    if dropped:
        notes.append(f"friction {', '.join(repr(d) for d in dropped)} acted inside a merged body and "
                     f"{'was' if len(dropped) == 1 else 'were'} dropped")
    if shared:
        listed = ", ".join(repr(d) for d in shared[:3]) + (f" and {len(shared) - 3} more" if len(shared) > 3 else "")
        notes.append(f"friction {listed} acted on removed bodies between kept ones and "
                     f"{'was' if len(shared) == 1 else 'were'} shared among them (viscous and Coulomb "
                     "parts in proportion)")

    # actuators and sensors: must land on one kept body (and one reaction/reference) with unit ratio
    actuators = {}
    for (name, act), load in zip(lumped.actuators.items(), mech.actuators):
        body, reaction = _single_target(T.T @ load.vector, kept, f"the actuator {name!r}")
        if body is None:
            raise ModelError(f"the actuator {name!r} and its reaction would act on the same merged body; "
                             "keep its body and its reaction body apart", path="keep", value=kept)
        actuators[name] = {"body": body} | ({"reaction": reaction} if reaction else {})
    sensors = {}
    for (name, sensor), meas in zip(lumped.sensors.items(), mech.sensors):
        body, ref = _single_target(meas.vector @ T, kept, f"the sensor {name!r}")
        if body is None:
            raise ModelError(f"the sensor {name!r} would measure a merged body relative to itself; keep "
                             "its body and its reference body apart", path="keep", value=kept)
        entry = sensor.model_dump(exclude_none=True)
        entry.pop("relative_to", None)
        entry.update({"body": body} | ({"relative_to": ref} if ref else {}))
        sensors[name] = entry

    bodies = {}
    for a, name in enumerate(kept):
        key = "mass" if kinds[name] == "translational" else "inertia"
        bodies[name] = {key: _tidy(masses[a])}
    data = {"type": "lumped", "bodies": bodies, "couplings": couplings, "frictions": frictions,
            "actuators": actuators, "sensors": sensors}
    from pydantic import ValidationError

    try:
        new_spec = LumpedSpec.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise ModelError(f"the regrouped model is not valid: {first['msg']}", path=where or "keep",
                         value=kept) from None
    return new_spec, notes, merged_into


# --------------------------------------------------------------------------- model file
def reduced_machine(machine: "Machine", axis: str | None, spec: LumpedSpec, *,
                    merged_into: Mapping[str, str] | None = None) -> "Machine":
    """The machine with one axis's mechanics replaced by a reduced lumped model.

    Built with ``model_copy(update=...)`` on the axis and the machine, then validated like a model
    file (drive, controller and tool references must still resolve), so it can be written with
    :func:`sicomat.io.modelfile.save_model`. An axis ``tool`` that was merged is moved to the body it
    was merged into (``merged_into``, as in :attr:`ReductionResult.merged_into`).

    Examples
    --------
    >>> from sicomat.description import Machine
    >>> machine = Machine(axes={"X": {"mechanics": {"type": "chain", "masses": [1, 1, 1],
    ...                                             "stiffnesses": [1e6, 1e3]}}})
    >>> res = physical_reduction(machine.axis("X").mechanics, keep=["m2", "m3"])
    >>> sorted(reduced_machine(machine, "X", res.spec).axis("X").mechanics.bodies)
    ['m2', 'm3']
    """
    from pydantic import ValidationError

    from ..description.machine import Machine

    name = machine.axis_name(axis)
    old = machine.axes[name]
    update: dict[str, Any] = {"mechanics": spec}
    if old.tool is not None and old.tool not in spec.bodies:
        target = (merged_into or {}).get(old.tool)
        if target is None or target == GROUND:
            raise ModelError(f"the axis tool {old.tool!r} was merged away; keep it or name where it went",
                             path=f"axes.{name}.tool", value=old.tool)
        update["tool"] = target
    new_axis = old.model_copy(update=update)
    description = (machine.description + " " if machine.description else "") + \
        f"[axis {name}: physical regrouping onto {', '.join(spec.bodies)}]"
    new = machine.model_copy(update={"axes": {**machine.axes, name: new_axis}, "description": description})
    try:
        return Machine.model_validate(new.model_dump(mode="json", exclude_none=True))
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise ModelError(f"the reduced machine is not valid: {first['msg']}", path=where) from None
