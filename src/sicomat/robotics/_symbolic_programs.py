"""The straight-line programs behind :mod:`sicomat.robotics.symbolic`: the symbol policy of a robot,
SYMORO's symbol manager (every non-trivial entry named as it is computed) and the three recursions
written with it — the transforms ``0T_j`` (notes §2.1), Newton–Euler (§2.3) and composite links (§2.4)
of ``shared/reference/robotics-formalism.md``, the same equations as the numeric core."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

import sympy

if TYPE_CHECKING:
    from .table import MDHRobot

__all__ = ["Equations", "Policy", "symbol", "transforms_program", "newton_euler_program", "composite_program"]

_AXES = "xyz"
# An angle within this of a multiple of pi/2 is taken as that multiple: a table writes pi/2 as
# math.pi/2 (exact to 1e-16) or as a rounded decimal; 1e-12 rad is far below any real tilt.
_RIGHT_ANGLE_TOL = 1e-12
_GEOMETRY = ("gamma", "b", "alpha", "d", "theta", "r")
_DYNAMICS = ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M", "IA", "FV", "FS")
Outputs = list[tuple[str, sympy.Expr]]


def symbol(name: str) -> sympy.Symbol:
    """A real symbol: every symbol of the models is made here, so all share the assumption."""
    return sympy.Symbol(name, real=True)


class Equations:
    """SYMORO's symbol manager: names the non-trivial entries in the order they are computed."""

    def __init__(self) -> None:
        self.assignments: list[tuple[sympy.Symbol, sympy.Expr]] = []
        self._known: dict[sympy.Expr, sympy.Symbol] = {}
        self._labels: set[str] = set()

    def name(self, expr: sympy.Expr, label: str) -> sympy.Expr:
        """``expr`` itself if it is a number or a symbol (or its negation), else the symbol ``label``
        assigned to it — or the symbol an equal expression (or its negation) already has."""
        expr = sympy.sympify(expr)
        if expr.is_Atom or (-expr).is_Atom:
            return expr
        if expr in self._known:
            return self._known[expr]
        if -expr in self._known:
            return -self._known[-expr]
        if label in self._labels:       # two values under one name would silently alias: a bug here
            raise RuntimeError(f"internal error: the intermediate {label} is named twice")
        self._labels.add(label)
        named = symbol(label)
        self.assignments.append((named, expr))
        self._known[expr] = named
        return named

    def vector(self, v: sympy.Matrix, label: str) -> sympy.Matrix:
        """A 3-vector with its entries named ``<label>x``, ``<label>y``, ``<label>z``."""
        return sympy.Matrix([self.name(v[k], f"{label}{_AXES[k]}") for k in range(3)])

    def matrix(self, m: sympy.Matrix, label: str) -> sympy.Matrix:
        """A 3x3 matrix with its entries named ``<label>xx``, ``<label>xy``..."""
        return sympy.Matrix(3, 3, lambda r, c: self.name(m[r, c], f"{label}{_AXES[r]}{_AXES[c]}"))


class Policy:
    """The symbols of a robot: joint variables, parameters (with values), constants made exact."""

    def __init__(self, robot: "MDHRobot") -> None:
        self.robot = robot
        n = robot.n_joints
        self.q = tuple(symbol(f"q{k + 1}") for k in range(n))
        self.qd = tuple(symbol(f"qd{k + 1}") for k in range(n))
        self.qdd = tuple(symbol(f"qdd{k + 1}") for k in range(n))
        self.parameters: dict[sympy.Symbol, float] = {}
        self.geometry = [{f: self._geometric(f, row) for f in _GEOMETRY} for row in range(robot.n_frames)]
        self.chi = [[self._parameter(f"{f}{row + 1}", float(robot.chi[row, c])) for c, f in enumerate(_DYNAMICS)]
                    for row in range(robot.n_frames)]
        self.gravity = sympy.Matrix([self._parameter(f"G{k + 1}", float(robot.gravity[k])) for k in range(3)])

    def _parameter(self, name: str, value: float) -> sympy.Expr:
        if value == 0.0:
            return sympy.S.Zero
        named = symbol(name)
        self.parameters[named] = value
        return named

    def _geometric(self, field: str, row: int) -> sympy.Expr:
        value = float(getattr(self.robot, field)[row])
        if field in ("gamma", "alpha", "theta"):
            quarter = round(value / (math.pi / 2))
            if abs(value - quarter * math.pi / 2) <= _RIGHT_ANGLE_TOL:
                return sympy.Rational(quarter, 2) * sympy.pi
        return self._parameter(f"{field}{row + 1}", value)

    def joint(self, row: int, values: Sequence[sympy.Symbol]) -> sympy.Expr:
        k = int(self.robot.joint_of_frame[row])
        return values[k] if k >= 0 else sympy.S.Zero

    def local(self, eq: Equations, row: int) -> tuple[sympy.Matrix, sympy.Matrix]:
        """``a(j)R_j`` and ``a(j)P_j`` of frame ``row + 1`` from named cos/sin (§1.2 of the notes)."""
        j, geo, sigma = row + 1, self.geometry[row], int(self.robot.sigma[row])
        theta = geo["theta"] + (self.joint(row, self.q) if sigma == 0 else 0)
        r = geo["r"] + (self.joint(row, self.q) if sigma == 1 else 0)

        def rot_z(angle: sympy.Expr, tag: str) -> sympy.Matrix:
            c, s = eq.name(sympy.cos(angle), f"C{tag}{j}"), eq.name(sympy.sin(angle), f"S{tag}{j}")
            return sympy.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])

        rz_g = rot_z(geo["gamma"], "G")
        ca, sa = eq.name(sympy.cos(geo["alpha"]), f"CA{j}"), eq.name(sympy.sin(geo["alpha"]), f"SA{j}")
        const = rz_g * sympy.Matrix([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
        rot = const * rot_z(theta, "")
        pos = sympy.Matrix([0, 0, geo["b"]]) + const[:, 0] * geo["d"] + const[:, 2] * r
        rot = sympy.Matrix(3, 3, lambda a, b: eq.name(rot[a, b], f"R{j}_{a + 1}{b + 1}"))
        pos = sympy.Matrix([eq.name(pos[k], f"P{j}_{k + 1}") for k in range(3)])
        return rot, pos


_EZ = sympy.Matrix([0, 0, 1])


def _skew(v: sympy.Matrix) -> sympy.Matrix:
    return sympy.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _inertia(chi: Sequence[sympy.Expr]) -> sympy.Matrix:
    xx, xy, xz, yy, yz, zz = chi[:6]
    return sympy.Matrix([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def transforms_program(policy: Policy) -> tuple[Equations, Outputs]:
    eq = Equations()
    rot = [sympy.eye(3)]
    pos = [sympy.zeros(3, 1)]
    for row in range(policy.robot.n_frames):
        j, a = row + 1, int(policy.robot.ant[row])
        r_local, p_local = policy.local(eq, row)
        rot.append(sympy.Matrix(3, 3, lambda u, v: eq.name((rot[a] * r_local)[u, v], f"R0{j}_{u + 1}{v + 1}")))
        pos.append(sympy.Matrix([eq.name((pos[a] + rot[a] * p_local)[k], f"P0{j}_{k + 1}") for k in range(3)]))
    outputs = []
    for j in range(policy.robot.n_frames + 1):
        t = rot[j].row_join(pos[j]).col_join(sympy.Matrix([[0, 0, 0, 1]]))
        outputs += [(f"T{j}_{u + 1}{v + 1}", t[u, v]) for u in range(4) for v in range(4)]
    return eq, outputs


def _torque(policy: Policy, row: int, sigma: int, f: sympy.Matrix, n: sympy.Matrix, at_rest: bool) -> sympy.Expr:
    if at_rest:
        return f[2] if sigma == 1 else n[2]
    ia, fv, fs = policy.chi[row][10:13]
    qd, qdd = policy.joint(row, policy.qd), policy.joint(row, policy.qdd)
    return (f[2] if sigma == 1 else n[2]) + ia * qdd + fv * qd + fs * sympy.sign(qd)


def newton_euler_program(policy: Policy, at_rest: bool = False) -> tuple[Equations, Outputs]:
    """Torques by the Newton–Euler recursion of the notes §2.3, every entry named on the way; with
    ``at_rest`` (``qd = qdd = 0``) the gravity torques alone."""
    robot, eq = policy.robot, Equations()
    nf, zero = robot.n_frames, sympy.zeros(3, 1)
    w, wd, vd, u = [zero], [zero], [-policy.gravity], [sympy.zeros(3, 3)]
    local, forces, moments = [], [], []
    for row in range(nf):
        j, a, sigma = row + 1, int(robot.ant[row]), int(robot.sigma[row])
        rot, pos = policy.local(eq, row)
        local.append((rot, pos))
        qd, qdd = (sympy.S.Zero, sympy.S.Zero) if at_rest else (policy.joint(row, policy.qd),
                                                                 policy.joint(row, policy.qdd))
        wi = eq.vector(rot.T * w[a], f"WI{j}")
        vs = eq.vector(vd[a] + u[a] * pos, f"VS{j}")
        vdj = rot.T * vs
        wdj = rot.T * wd[a]
        if sigma == 0:
            wj = wi + qd * _EZ
            wdj += qdd * _EZ + wi.cross(qd * _EZ)
        else:
            wj = wi
            if sigma == 1:
                vdj += qdd * _EZ + 2 * wi.cross(qd * _EZ)
        w.append(eq.vector(wj, f"W{j}"))
        wd.append(eq.vector(wdj, f"WP{j}"))
        vd.append(eq.vector(vdj, f"VP{j}"))
        u.append(eq.matrix(_skew(wd[j]) + _skew(w[j]) * _skew(w[j]), f"U{j}"))
        chi = policy.chi[row]
        ms, mass, inertia = sympy.Matrix(chi[6:9]), chi[9], _inertia(chi)
        forces.append(eq.vector(mass * vd[j] + u[j] * ms, f"F{j}"))
        jw = eq.vector(inertia * w[j], f"JW{j}")
        moments.append(eq.vector(inertia * wd[j] + w[j].cross(jw), f"N{j}") + ms.cross(vd[j]))
    torques: dict[int, sympy.Expr] = {}
    for row in reversed(range(nf)):
        j, a, sigma = row + 1, int(robot.ant[row]), int(robot.sigma[row])
        f, n = eq.vector(forces[row], f"FT{j}"), eq.vector(moments[row], f"NT{j}")
        if sigma != 2:
            torques[int(robot.joint_of_frame[row])] = _torque(policy, row, sigma, f, n, at_rest)
        if a > 0:
            rot, pos = local[row]
            fa = eq.vector(rot * f, f"FDI{j}")
            forces[a - 1] = forces[a - 1] + fa
            moments[a - 1] = moments[a - 1] + rot * n + pos.cross(fa)
    return eq, [(f"tau{k + 1}", torques[k]) for k in range(robot.n_joints)]


def composite_program(policy: Policy) -> tuple[Equations, Outputs]:
    """The inertia matrix by composite links, the notes §2.4."""
    robot, eq = policy.robot, Equations()
    nf, n = robot.n_frames, robot.n_joints
    local = [policy.local(eq, row) for row in range(nf)]
    jp = [_inertia(policy.chi[row]) for row in range(nf)]
    msp = [sympy.Matrix(policy.chi[row][6:9]) for row in range(nf)]
    mp = [policy.chi[row][9] for row in range(nf)]
    entries: dict[tuple[int, int], sympy.Expr] = {}
    for row in reversed(range(nf)):     # the composite link of frame row+1 is complete here
        j, a = row + 1, int(robot.ant[row])
        jp[row] = eq.matrix(jp[row], f"JP{j}")
        msp[row] = eq.vector(msp[row], f"MSP{j}")
        mp[row] = eq.name(mp[row], f"MP{j}")
        if a > 0:
            rot, pos = local[row]
            s = eq.vector(rot * msp[row], f"MSR{j}")
            ps = _skew(pos)
            jp[a - 1] = jp[a - 1] + rot * jp[row] * rot.T - (ps * _skew(s) + _skew(s) * ps) - mp[row] * ps * ps
            msp[a - 1] = msp[a - 1] + s + pos * mp[row]
            mp[a - 1] = mp[a - 1] + mp[row]
    for row in range(nf):
        sigma = int(robot.sigma[row])
        if sigma == 2:
            continue
        col, j = int(robot.joint_of_frame[row]), row + 1
        if sigma == 0:
            f, m = _EZ.cross(msp[row]), jp[row][:, 2]
        else:
            f, m = mp[row] * _EZ, msp[row].cross(_EZ)
        entries[col, col] = (f[2] if sigma == 1 else m[2]) + policy.chi[row][10]
        k = row
        while int(robot.ant[k]) > 0:
            rot, pos = local[k]
            a_row = int(robot.ant[k]) - 1
            f = eq.vector(rot * f, f"FA{j}_{a_row + 1}")
            m = eq.vector(rot * m + pos.cross(f), f"NA{j}_{a_row + 1}")
            if int(robot.sigma[a_row]) != 2:
                other = int(robot.joint_of_frame[a_row])
                entries[col, other] = entries[other, col] = f[2] if robot.sigma[a_row] == 1 else m[2]
            k = a_row
    outputs = [(f"A{r + 1}_{c + 1}", entries.get((r, c), sympy.S.Zero)) for r in range(n) for c in range(n)]
    return eq, outputs
