"""Lumped mechanics: the matrices M, D (μ) and K of eq. (3), with named dofs, actuators and sensors."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Literal, Sequence

import numpy as np

from ..description.mechanics import GROUND, LumpedSpec, geared_kind, resolve_stretch
from ..errors import ModelError
from .conditioning import check_numeric_range, check_resolvable
from .statespace import MassFactor

if TYPE_CHECKING:  # pragma: no cover
    from .modal import ModalResult
    from ..description.registry import MechanicsKind
    from ..lti.plant import Plant

__all__ = ["Dof", "Link", "Load", "Measurement", "Mechanics", "build_mechanics", "check_axis_mechanics"]


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Dof:
    """A degree of freedom: the body's name and whether it translates (m) or rotates (rad)."""

    name: str
    kind: Literal["translational", "rotational"]

    @property
    def position(self) -> str:
        """Signal name of the position, ``"<body>.x"`` or ``"<body>.theta"``."""
        return f"{self.name}.x" if self.kind == "translational" else f"{self.name}.theta"

    @property
    def velocity(self) -> str:
        """Signal name of the velocity, ``"<body>.v"`` or ``"<body>.omega"``."""
        return f"{self.name}.v" if self.kind == "translational" else f"{self.name}.omega"

    @property
    def load(self) -> str:
        """Name of an external load on this dof, ``"<body>.force"`` or ``"<body>.torque"``."""
        return f"{self.name}.force" if self.kind == "translational" else f"{self.name}.torque"


@dataclass(frozen=True, eq=False)
class Link:
    """A coupling or friction lowered to a stretch vector ``g`` (stretch = g · q) and its coefficients."""

    name: str
    g: np.ndarray
    kind: Literal["translational", "rotational"]
    stiffness: float = 0.0
    damping: float = 0.0
    coulomb: float = 0.0
    static: float = 0.0


@dataclass(frozen=True, eq=False)
class Load:
    """An actuator: the generalised force vector it applies per unit of command (N or N·m)."""

    name: str
    vector: np.ndarray
    kind: Literal["translational", "rotational"]


@dataclass(frozen=True, eq=False)
class Measurement:
    """A sensor: its output is ``vector · q`` (position) or ``vector · q̇`` (velocity)."""

    name: str
    vector: np.ndarray
    kind: Literal["position", "velocity"]
    unit: Literal["translational", "rotational"]
    step: float | None = None


@dataclass(frozen=True, eq=False)
class Mechanics:
    """A lumped mechanical model ``M q̈ + D q̇ + K q = B_u u`` with named dofs (SI units).

    Build it with :func:`build_mechanics` from a description, or with :meth:`from_matrices` from
    matrices computed elsewhere (a full, symmetric positive definite M is allowed). Matrices are
    read-only ``(n, n)`` arrays in the order of :attr:`dofs`. ``couplings`` and ``frictions`` keep
    the elements (for the simulator's Coulomb friction and for physical model reduction); the
    couplings explain the stiffness, ``K = Σ k g gᵀ`` (the rigid modes and the undamped modes are
    computed from them).
    """

    dofs: tuple[Dof, ...]
    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    actuators: tuple[Load, ...] = ()
    sensors: tuple[Measurement, ...] = ()
    couplings: tuple[Link, ...] = ()
    frictions: tuple[Link, ...] = ()
    _index: dict[str, int] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        for name in ("mass", "damping", "stiffness"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        object.__setattr__(self, "_index", {d.name: i for i, d in enumerate(self.dofs)})

    @property
    def n(self) -> int:
        """Number of degrees of freedom."""
        return len(self.dofs)

    @property
    def dof_names(self) -> tuple[str, ...]:
        """Body names in dof order."""
        return tuple(d.name for d in self.dofs)

    @cached_property
    def mass_factor(self) -> MassFactor:
        """The Cholesky factor of M (:class:`~sicomat.mechanics.statespace.MassFactor`), made once."""
        return MassFactor(self.mass)

    @property
    def lumped(self) -> bool:
        """True when M is diagonal (one mass or inertia per body, as every model file gives)."""
        return self.mass_factor.diagonal

    def lumped_masses(self, what: str) -> np.ndarray:
        """The bodies' masses or inertias (M's diagonal) for a method ``what`` that is defined only
        for a diagonal M; a :class:`~sicomat.errors.ModelError` naming ``what`` for a full M."""
        if not self.lumped:
            raise ModelError(f"{what} is defined for lumped bodies (a diagonal mass matrix); this "
                             "mechanics has a full mass matrix", path="mass")
        return np.diag(self.mass).copy()

    @classmethod
    def from_matrices(cls, dofs: Sequence[Dof | str], mass, damping, stiffness, *,
                      actuators: Sequence[Load] = (), sensors: Sequence[Measurement] = (),
                      couplings: Sequence[Link] | None = None, frictions: Sequence[Link] = ()) -> "Mechanics":
        """A mechanics from matrices computed outside the model file (robotics, FE, ...).

        Parameters
        ----------
        dofs : sequence of Dof or str
            The dofs in matrix order; a name alone is a translational dof.
        mass, damping, stiffness : array_like, (n, n)
            M symmetric positive definite (full or diagonal), D and K symmetric positive semidefinite.
        actuators, sensors, frictions : optional
            As built by :func:`build_mechanics`, vectors of length n.
        couplings : sequence of Link, optional
            The springs that make K (``K = Σ k g gᵀ`` is checked to ``1e-10·max|K|``). Without them
            K is split into its eigen-components ``λ v vᵀ`` (λ above ``n·ε·λ_max``), named
            ``"K.1"``, ``"K.2"``, ...: the rigid modes are then K's null space to that tolerance
            rather than the exact geometry of named springs.

        Raises
        ------
        ModelError
            Shapes that disagree, a non-symmetric D or K, an M that is not symmetric positive
            definite, a K with a negative eigenvalue, couplings that do not make K.

        Examples
        --------
        >>> mech = Mechanics.from_matrices(["a", "b"], [[2.0, 1.0], [1.0, 2.0]], np.zeros((2, 2)),
        ...                                [[1.0, -1.0], [-1.0, 1.0]])
        >>> mech.lumped, mech.rigid_modes().shape, [c.name for c in mech.couplings]
        (False, (2, 1), ['K.1'])
        """
        dof_list = tuple(d if isinstance(d, Dof) else Dof(str(d), "translational") for d in dofs)
        n = len(dof_list)
        matrices = {}
        for key, value in (("mass", mass), ("damping", damping), ("stiffness", stiffness)):
            a = np.asarray(value, dtype=float)
            if a.shape != (n, n):
                raise ModelError(f"expected an ({n}, {n}) matrix for {n} dofs, got shape {a.shape}", path=key)
            if not np.all(np.isfinite(a)):
                raise ModelError("the matrix has non-finite entries", path=key)
            if key != "mass" and np.max(np.abs(a - a.T), initial=0.0) > 1e-12 * np.max(np.abs(a), initial=0.0):
                raise ModelError("the matrix is not symmetric", path=key)
            matrices[key] = 0.5 * (a + a.T)
        MassFactor(mass)                              # located error if M is not SPD (or not symmetric)
        K = matrices["stiffness"]
        scale = float(np.max(np.abs(K), initial=0.0))
        if couplings is None:
            couplings = _stiffness_links(K, dof_list)
        else:
            couplings = tuple(couplings)
            made = sum((link.stiffness * np.outer(link.g, link.g) for link in couplings), np.zeros((n, n)))
            if np.max(np.abs(made - K), initial=0.0) > 1e-10 * max(scale, float(np.max(np.abs(made), initial=0.0))):
                raise ModelError("the couplings do not make the stiffness matrix (K = Σ k g gᵀ)",
                                 path="couplings")
        for group, items in (("actuators", actuators), ("sensors", sensors), ("frictions", frictions)):
            for item in items:
                vector = item.g if isinstance(item, Link) else item.vector
                if np.shape(vector) != (n,):
                    raise ModelError(f"expected a vector of length {n}", path=f"{group}.{item.name}")
        return cls(dofs=dof_list, mass=matrices["mass"], damping=matrices["damping"], stiffness=K,
                   actuators=tuple(actuators), sensors=tuple(sensors), couplings=couplings,
                   frictions=tuple(frictions))

    def index(self, body: str) -> int:
        """Position of ``body`` in the dof vector."""
        return self._index[body]

    def rigid_modes(self) -> np.ndarray:
        """An orthonormal basis ``(n, r)`` of the rigid-body motions (the null space of K).

        Computed from the couplings' stretch vectors (ratios of order one), not from K's entries,
        so stiffness ratios of 1e12 do not blur it.
        """
        active = [link.g for link in self.couplings if link.stiffness > 0]
        if not active:
            return np.eye(self.n)
        import scipy.linalg

        return scipy.linalg.null_space(np.vstack(active), rcond=1e-10)

    def actuator(self, name: str) -> Load:
        """The actuator called ``name``."""
        return next(a for a in self.actuators if a.name == name)

    def sensor(self, name: str) -> Measurement:
        """The sensor called ``name``."""
        return next(s for s in self.sensors if s.name == name)

    def rigid_motion(self, actuator: np.ndarray, tool: np.ndarray) -> tuple[np.ndarray, float]:
        """The rigid-body motion the actuator drives, scaled to a unit tool displacement.

        Returns ``(phi, m_rigid)``: ``phi`` (n,) with ``tool · phi = 1``, and the rigid mass or
        inertia seen by the actuator, ``m_rigid = u / (tool acceleration)`` (kg for a linear motor on
        a linear axis, N·m·s²/m for a rotary motor on a linear axis). Without a free rigid motion,
        the static deflection shape ``K⁻¹ actuator`` stands in for it.
        """
        rigid = self.rigid_modes()
        if rigid.shape[1]:
            direction = rigid @ np.linalg.solve(rigid.T @ self.mass @ rigid, rigid.T @ actuator)
        else:
            direction = np.linalg.solve(self.stiffness, actuator)
        reach = float(tool @ direction)
        if abs(reach) < 1e-12 * np.linalg.norm(direction) * max(float(np.linalg.norm(tool)), 1.0):
            raise ModelError("the actuator cannot move the tool body in a rigid-body motion; "
                             "check the actuator, the couplings' ratios and the tool body")
        phi = direction / reach
        return phi, float(phi @ self.mass @ phi) / float(phi @ actuator)

    def state_space(self, **kwargs) -> "Plant":
        """The state space of eqs. (11)–(12); see :func:`sicomat.mechanics.statespace.mechanics_plant`."""
        from .statespace import mechanics_plant

        return mechanics_plant(self, **kwargs)

    def modes(self) -> "ModalResult":
        """Modal analysis; see :func:`sicomat.mechanics.modal.modal_analysis`. Computed once per mechanics (it
        is immutable): the frequency grids of every loop response and the tuning ask for it again and again."""
        cached = self.__dict__.get("_modes")
        if cached is None:
            from .modal import modal_analysis

            cached = modal_analysis(self)
            object.__setattr__(self, "_modes", cached)
        return cached


def _stiffness_links(K: np.ndarray, dofs: tuple[Dof, ...]) -> tuple[Link, ...]:
    """K split into rank-one springs ``λ v vᵀ`` (its eigen-components above ``n·ε·λ_max``)."""
    n = K.shape[0]
    if not np.any(K):
        return ()
    lam, vectors = np.linalg.eigh(K)
    tol = n * np.finfo(float).eps * float(np.max(np.abs(lam)))
    if lam[0] < -tol:
        raise ModelError(f"the stiffness matrix has a negative eigenvalue ({lam[0]:.6g}); a passive "
                         "mechanics has K positive semidefinite", path="stiffness")
    kinds = {d.kind for d in dofs}
    kind = kinds.pop() if len(kinds) == 1 else "translational"
    keep = np.flatnonzero(lam > tol)[::-1]            # stiffest first
    return tuple(Link(f"K.{i + 1}", _frozen(vectors[:, j]), kind, stiffness=float(lam[j]))
                 for i, j in enumerate(keep))


def build_mechanics(spec: "MechanicsKind") -> Mechanics:
    """Assemble M, D, K, actuators and sensors from a mechanics description (any registered kind:
    its ``to_lumped()`` is the one lowering, see :mod:`sicomat.description.registry`).

    Each coupling with stretch vector ``g`` (``g[a] = r_a``, ``g[b] = -r_b``) adds ``k g gᵀ`` to K
    and ``c g gᵀ`` to D; viscous friction adds to D the same way; an actuator on body ``a`` with
    reaction on ``b`` applies ``+u`` to ``a`` and ``-u`` to ``b``.

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> mech = build_mechanics(ChainSpec(type="chain", masses=[1, 2], stiffnesses=[100]))
    >>> mech.stiffness.tolist()
    [[100.0, -100.0], [-100.0, 100.0]]
    """
    lumped: LumpedSpec = spec.to_lumped()
    dofs = tuple(Dof(name, body.kind) for name, body in lumped.bodies.items())
    index = {d.name: i for i, d in enumerate(dofs)}
    n = len(dofs)

    def stretch_vector(between, ratios) -> np.ndarray:
        g = np.zeros(n)
        for end, ratio, sign in zip(between, ratios, (1.0, -1.0)):
            if end != GROUND:
                g[index[end]] += sign * ratio
        return g

    kinds = {name: body.kind for name, body in lumped.bodies.items()}
    couplings = tuple(
        Link(name, _frozen(stretch_vector(c.between, c.ratios)), resolve_stretch(c.stretch, c.between, kinds),
             stiffness=c.stiffness, damping=c.damping)
        for name, c in lumped.couplings.items())
    frictions = tuple(
        Link(name, _frozen(stretch_vector(f.between, f.ratios)), resolve_stretch(f.stretch, f.between, kinds),
             damping=f.viscous, coulomb=f.coulomb, static=f.static if f.static is not None else f.coulomb)
        for name, f in lumped.frictions.items())

    mass = np.diag([body.value for body in lumped.bodies.values()])
    G = np.array([link.g for link in couplings]).reshape(len(couplings), n)
    Gf = np.array([link.g for link in frictions]).reshape(len(frictions), n)
    k = np.array([link.stiffness for link in couplings])
    c = np.array([link.damping for link in couplings])
    v = np.array([link.damping for link in frictions])
    stiffness = G.T @ (k[:, None] * G)          # Σ k g gᵀ
    damping = G.T @ (c[:, None] * G) + Gf.T @ (v[:, None] * Gf)
    stiffness = 0.5 * (stiffness + stiffness.T)  # exactly symmetric despite the product's rounding
    damping = 0.5 * (damping + damping.T)

    actuators = []
    for name, act in lumped.actuators.items():
        vector = np.zeros(n)
        vector[index[act.body]] = act.ratio
        if act.reaction is not None:
            vector[index[act.reaction]] = -act.ratio
        actuators.append(Load(name, _frozen(vector), geared_kind(act, kinds)))
    sensors = []
    for name, sensor in lumped.sensors.items():
        vector = np.zeros(n)
        vector[index[sensor.body]] = sensor.ratio
        if sensor.relative_to is not None:
            vector[index[sensor.relative_to]] -= sensor.ratio
        sensors.append(Measurement(name, _frozen(vector), sensor.kind, geared_kind(sensor, kinds),
                                   step=sensor.step))


    check_numeric_range({**{f"bodies.{name}.{'mass' if body.mass is not None else 'inertia'}": body.value
                            for name, body in lumped.bodies.items()},
                         **{f"couplings.{link.name}.{key}": getattr(link, key)
                            for link in couplings for key in ("stiffness", "damping")},
                         **{f"frictions.{link.name}.{key}": value for link in frictions
                            for key, value in (("viscous", link.damping), ("coulomb", link.coulomb),
                                               ("static", link.static))}})
    mech = Mechanics(dofs=dofs, mass=mass, damping=damping, stiffness=stiffness,
                     actuators=tuple(actuators), sensors=tuple(sensors),
                     couplings=couplings, frictions=frictions)
    return mech


def check_axis_mechanics(axis: str, spec) -> "Mechanics":
    """The mechanics of axis ``axis`` built from ``spec`` and checked (range and resolvable poles),
    an error located at ``axes.<axis>.mechanics...``."""
    try:
        mech = build_mechanics(spec)
        check_resolvable(mech)
    except ModelError as exc:
        raise ModelError(exc.message, path=f"axes.{axis}.{exc.path}" if exc.path else f"axes.{axis}",
                         value=exc.value, has_value=exc.has_value) from None
    return mech
