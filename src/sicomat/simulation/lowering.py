"""Lowering of a :class:`~sicomat.servo.program.HybridProgram` to the flat arrays the compiled
kernel (:mod:`sicomat.simulation.kernel`) reads: op codes and operands, sparse rows of the linear
blocks, slot lists, and the discretised continuous part in the kernel's layout.

Internal to :mod:`sicomat.simulate`: every slot index and shape is checked here, so that the
kernel itself checks nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sicomat.errors import ModelError
from .continuous import _kernel_layout, active_links
from ..servo.program import (ClampGate, CurrentLimit, Delay, HybridProgram, LinearOutput, LinearUpdate, Quantize, Saturate, Setpoint, Sum)

# op codes, and the int / float operands each op row carries (see lower_ops)
LIN_OUT, LIN_UPD, SUM, SAT, QUANT, DELAY, CURLIM, CLAMP, SETPOINT = range(9)
NIP = 4
NFP = 5


@dataclass(eq=False)
class Lowered:
    """A program as flat arrays: ``struct`` (must agree across batch variants) and ``nums``."""

    struct: dict[str, np.ndarray]
    nums: dict[str, np.ndarray]
    nx: int
    links: np.ndarray
    n_links: int

    def structure_key(self) -> tuple:
        """The structure as one hashable value (equal keys: the variants can share a batch)."""
        return tuple((a.shape, a.tobytes()) for a in self.struct.values())


def slot_index(value: int, n_slots: int, what: str, *args) -> int:
    """``value`` as a slot index, checked; the message is ``what.format(*args)`` (formatted only
    on error: lowering checks every slot)."""
    v = int(value)
    if not 0 <= v < n_slots:
        raise ModelError(f"{what.format(*args)} must be a slot index in [0, {n_slots})", value=value)
    return v


def slot_indices(values: Sequence[int], n_slots: int, what: str, *args) -> list[int]:
    return [slot_index(v, n_slots, what, *args) for v in values]


class Flat:
    """Growing flat int (slot lists, sparse rows) and float (coefficients, weights) lists with
    offsets (Python lists: the pieces are a few numbers each)."""

    def __init__(self, n_slots: int) -> None:
        self.n_slots = n_slots
        self.idx: list[int] = []
        self.floats: list[float] = []

    @property
    def f_len(self) -> int:
        return len(self.floats)

    def add_floats(self, values) -> int:
        off = len(self.floats)
        self.floats.extend(float(v) for v in values)
        return off

    def add_ints(self, values: Sequence[int], what: str, *args) -> int:
        off = len(self.idx)
        self.idx.extend(slot_indices(values, self.n_slots, what, *args))
        return off


def block_matrices(blk, b: int) -> tuple[np.ndarray, ...]:
    """``A, B, C, D`` of block ``b`` as float arrays of consistent shapes."""
    Ab = np.atleast_2d(np.asarray(blk.A, dtype=float)) if np.size(blk.A) else np.zeros((0, 0))
    nxb, nin, nout = Ab.shape[0], len(blk.inputs), len(blk.outputs)
    try:
        return (Ab.reshape(nxb, nxb), np.asarray(blk.B, dtype=float).reshape(nxb, nin),
                np.asarray(blk.C, dtype=float).reshape(nout, nxb),
                np.asarray(blk.D, dtype=float).reshape(nout, nin))
    except ValueError:
        raise ModelError(f"block {b}: matrices do not match {nxb} states, {nin} inputs and "
                         f"{nout} outputs") from None


def block_patterns(programs: Sequence[HybridProgram]) -> list[tuple[np.ndarray, ...]] | None:
    """The non-zero pattern of every block's ``A, B, C, D``, united over ``programs`` (None when
    their blocks differ in number or shapes: the structure check reports it)."""
    patterns = None
    for p in programs:
        mats = [block_matrices(blk, b) for b, blk in enumerate(p.blocks)]
        masks = [tuple(m != 0.0 for m in ms) for ms in mats]
        if patterns is None:
            patterns = masks
            continue
        if len(masks) != len(patterns) or any(a.shape != b.shape for m, q in zip(masks, patterns)
                                               for a, b in zip(m, q)):
            return None
        patterns = [tuple(a | b for a, b in zip(m, q)) for m, q in zip(masks, patterns)]
    return patterns


def lower_blocks(blocks, flat: Flat,
                  patterns=None) -> tuple[list[tuple[int, ...]], list[np.ndarray]]:
    """Per block ``(nxb, n_out, update rows, output rows, outputs, state offset)`` and the initial
    states.

    ``x+ = A x + B u`` and ``y = C x + D u`` are stored as sparse rows: at offset ``p`` in ``idx``,
    row ``r`` is ``(f, ns, ni, ns state positions, ni input slots)`` with its ``ns + ni``
    coefficients at ``fdata[f:]``; the state terms come first, as in a dense product. The
    coefficients outside ``patterns`` (default: the non-zeros) are left out: they would add
    ``±0`` to a sum starting at ``+0.0``, which leaves it unchanged (only ``0 * inf`` or
    ``0 * nan`` would have made it NaN).
    """
    rows: list[tuple[int, ...]] = []
    xb0: list[np.ndarray] = []
    xs = 0
    n_slots = flat.n_slots
    for b, blk in enumerate(blocks):
        Ab, Bb, Cb, Db = block_matrices(blk, b)
        nxb, nout = Ab.shape[0], Cb.shape[0]
        inputs = slot_indices(blk.inputs, n_slots, "block {} input", b)
        masks = patterns[b] if patterns is not None else tuple(m != 0.0 for m in (Ab, Bb, Cb, Db))

        def sparse_rows(X, U, mX, mU):
            start = len(flat.idx)
            for xr, ur, kx, ku in zip(X.tolist(), U.tolist(), mX.tolist(), mU.tolist()):
                cx = [j for j, keep in enumerate(kx) if keep]
                cu = [j for j, keep in enumerate(ku) if keep]
                f = flat.add_floats([xr[j] for j in cx] + [ur[j] for j in cu])
                flat.idx += [f, len(cx), len(cu)] + [xs + j for j in cx] + [inputs[j] for j in cu]
            return start

        update = sparse_rows(Ab, Bb, masks[0], masks[1])
        output = sparse_rows(Cb, Db, masks[2], masks[3])
        outputs = flat.add_ints(blk.outputs, "block {} output", b)
        rows.append((nxb, nout, update, output, outputs, xs))
        x0 = np.zeros(nxb) if blk.x0 is None else np.asarray(blk.x0, dtype=float).reshape(nxb)
        xb0.append(x0)
        xs += nxb
    return rows, xb0


def lower_ops(ops, blocks: list[tuple[int, ...]], n_columns: int, flat: Flat):
    """The op list as ``op_code``, ``op_period``, ``op_phase``, ``op_ip`` (int operands), ``op_fp``
    (float operands) and the total delay-line length.

    ``op_ip`` rows by kind: LinearOutput ``(n_out, rows, outputs)``, LinearUpdate ``(nxb, rows,
    state)`` (the sparse rows of ``[C D]`` or ``[A B]`` and the outputs in ``idx``, the state
    offset; see :func:`lower_blocks`), Sum ``(n, inputs, output, weights)``, Saturate ``(input,
    output, lower_slot, upper_slot)``, Quantize ``(input, output, floor)``, Delay ``(input, output, samples, ring)``,
    CurrentLimit ``(speed, lower, upper)``, ClampGate ``(input, unsaturated, saturated, output)``,
    Setpoint ``(column, output)``.
    """
    n_slots = flat.n_slots
    codes, periods, phases, ints, floats = [], [], [], [], []
    n_delay = 0
    n_blocks = len(blocks)
    for o, op in enumerate(ops):
        period = int(op.period)
        if period < 1:
            raise ModelError(f"op {o}: period must be a positive number of base steps",
                             value=op.period)
        periods.append(period)
        phases.append(int(op.phase))
        fp: tuple = ()
        ip: tuple[int, ...]
        if isinstance(op, (LinearOutput, LinearUpdate)):
            if not 0 <= op.block < n_blocks:
                raise ModelError(f"op {o}: no block {op.block} ({n_blocks} blocks)")
            nxb, nout, update, output, outputs, xo = blocks[op.block]
            if isinstance(op, LinearOutput):
                code = LIN_OUT
                ip = (nout, output, outputs)
            else:
                code = LIN_UPD
                ip = (nxb, update, xo)
        elif isinstance(op, Sum):
            if len(op.inputs) != len(op.weights):
                raise ModelError(f"op {o}: Sum needs one weight per input",
                                 value=(op.inputs, op.weights))
            code = SUM
            ip = (len(op.inputs), flat.add_ints(op.inputs, "op {} input", o),
                  slot_index(op.output, n_slots, "op {} output", o), flat.add_floats(op.weights))
            fp = (op.offset,)
        elif isinstance(op, Saturate):
            code = SAT
            ip = (slot_index(op.input, n_slots, "op {} input", o),
                  slot_index(op.output, n_slots, "op {} output", o),
                  -1 if op.lower_slot < 0 else slot_index(op.lower_slot, n_slots, "op {} lower_slot", o),
                  -1 if op.upper_slot < 0 else slot_index(op.upper_slot, n_slots, "op {} upper_slot", o))
            fp = (op.lower, op.upper)
        elif isinstance(op, Quantize):
            if op.mode not in ("round", "floor"):
                raise ModelError(f"op {o}: Quantize mode must be 'round' or 'floor'", value=op.mode)
            if not (np.isfinite(op.step) and op.step > 0):
                raise ModelError(f"op {o}: Quantize step must be positive", value=op.step)
            code = QUANT
            ip = (slot_index(op.input, n_slots, "op {} input", o),
                  slot_index(op.output, n_slots, "op {} output", o), op.mode == "floor")
            fp = (op.step,)
        elif isinstance(op, Delay):
            if op.samples < 0:
                raise ModelError(f"op {o}: Delay samples must be >= 0", value=op.samples)
            code = DELAY
            ip = (slot_index(op.input, n_slots, "op {} input", o),
                  slot_index(op.output, n_slots, "op {} output", o), op.samples, n_delay)
            n_delay += int(op.samples)
        elif isinstance(op, CurrentLimit):
            if not op.i_peak > 0 or not op.u_max > 0:
                raise ModelError(f"op {o}: CurrentLimit needs i_peak > 0 and u_max > 0",
                                 value=(op.i_peak, op.u_max))
            code = CURLIM
            ip = (slot_index(op.speed, n_slots, "op {} speed", o),
                  slot_index(op.lower, n_slots, "op {} lower", o),
                  slot_index(op.upper, n_slots, "op {} upper", o))
            fp = (op.i_peak, op.u_max, op.resistance, op.ke, op.wl)
        elif isinstance(op, ClampGate):
            code = CLAMP
            ip = (slot_index(op.input, n_slots, "op {} input", o),
                  slot_index(op.unsaturated, n_slots, "op {} unsaturated", o),
                  slot_index(op.saturated, n_slots, "op {} saturated", o),
                  slot_index(op.output, n_slots, "op {} output", o))
        elif isinstance(op, Setpoint):
            if not 0 <= op.column < n_columns:
                raise ModelError(f"op {o}: Setpoint column must be in [0, {n_columns})",
                                 value=op.column)
            code = SETPOINT
            ip = (op.column, slot_index(op.output, n_slots, "op {} output", o))
        else:
            raise ModelError(f"op {o}: unknown op kind {type(op).__name__}")
        codes.append(code)
        ints.append(tuple(ip) + (0,) * (NIP - len(ip)))
        floats.append(tuple(fp) + (0.0,) * (NFP - len(fp)))
    n_ops = len(ops)
    op_code = np.array(codes, dtype=np.int64)
    op_period = np.array(periods, dtype=np.int64)
    op_phase = np.array(phases, dtype=np.int64)
    op_ip = np.array(ints, dtype=np.int64).reshape(n_ops, NIP)
    op_fp = np.array(floats, dtype=float).reshape(n_ops, NFP)
    return op_code, op_period, op_phase, op_ip, op_fp, n_delay


def lower(program: HybridProgram, record: Sequence[int] | None = None,
           patterns: list[tuple[np.ndarray, ...]] | None = None) -> Lowered:
    n_slots = program.n_slots
    cont = program.continuous
    A = np.atleast_2d(np.asarray(cont.A, dtype=float))
    nx = A.shape[0]
    in_slots = np.array(slot_indices(cont.input_slots, n_slots, "continuous input slot"), dtype=np.int64)
    out_slots = np.array(slot_indices(cont.output_slots, n_slots, "continuous output slot"),
                         dtype=np.int64)
    nu, ny = in_slots.size, out_slots.size
    try:
        np.asarray(cont.B, dtype=float).reshape(nx, nu)
        C = np.asarray(cont.C, dtype=float).reshape(ny, nx)
        D = np.asarray(cont.D, dtype=float).reshape(ny, nu)
    except ValueError:
        raise ModelError(f"continuous part: B, C, D must have shapes ({nx}, {nu}), ({ny}, {nx}), "
                         f"({ny}, {nu}) for {nx} states, {nu} input slots and {ny} output slots",
                         value=(np.shape(cont.B), np.shape(cont.C), np.shape(cont.D))) from None
    links = active_links(cont)
    n_links = np.asarray(cont.coulomb).size
    try:
        G_all = np.asarray(cont.G, dtype=float).reshape(n_links, nx) if n_links else np.zeros((0, nx))
        x0 = np.asarray(cont.x0, dtype=float).reshape(nx)
    except ValueError:
        raise ModelError(f"continuous part: G must have shape ({n_links}, {nx}) and x0 ({nx},)",
                         value=(np.shape(cont.G), np.shape(cont.x0))) from None
    G = np.ascontiguousarray(G_all[links])
    coulomb = np.asarray(cont.coulomb, dtype=float).reshape(-1)[links]
    static = np.asarray(cont.static, dtype=float).reshape(-1)[links]
    fr_all = tuple(cont.friction_slots)
    if fr_all and len(fr_all) != n_links:
        raise ModelError(f"friction_slots must name one slot (or -1) per friction link "
                         f"({n_links})", value=fr_all)
    fr_slots = np.array([-1 if int(fr_all[j]) < 0 else slot_index(fr_all[j], n_slots, "friction slot")
                         for j in links] if fr_all else [], dtype=np.int64)

    rec = program.record if record is None else tuple(record)
    rec_slots = np.array(slot_indices(rec, n_slots, "recorded slot"), dtype=np.int64)

    table = np.atleast_2d(np.asarray(program.table, dtype=float))
    if table.shape[1] == 0:
        table = np.zeros((table.shape[0], 1))

    flat = Flat(n_slots)
    blocks, xb0 = lower_blocks(program.blocks, flat, patterns)
    op_code, op_period, op_phase, op_ip, op_fp, n_delay = lower_ops(program.ops, blocks,
                                                                     table.shape[0], flat)
    xs = sum(x.size for x in xb0)
    struct = dict(op_code=op_code, op_period=op_period, op_phase=op_phase, op_ip=op_ip,
                  idx=np.array(flat.idx, dtype=np.int64), in_slots=in_slots,
                  out_slots=out_slots, fr_slots=fr_slots, rec_slots=rec_slots,
                  shapes=np.array([n_slots, nx, nu, ny, links.size, n_delay, flat.f_len, xs,
                                   *table.shape], dtype=np.int64),
                  links=links.astype(np.int64))
    nums = dict(op_fp=op_fp,
                fdata=np.array(flat.floats, dtype=float),
                xb0=np.concatenate(xb0) if xb0 else np.zeros(0),
                table=np.ascontiguousarray(table), CD=np.hstack([C, D]), G=G,
                coulomb=np.ascontiguousarray(coulomb),
                static=np.ascontiguousarray(static), x0=x0)
    return Lowered(struct, nums, nx, links, n_links)


def kernel_matrices(programs: Sequence[HybridProgram], links: np.ndarray,
                     levels: int) -> tuple[np.ndarray, ...]:
    """``[Phi Gamma]ᵀ`` (transposed), ``[Lx Lu Lf]`` and projections of every distinct continuous
    part, the index of each program's part in them, and the in-step event bounds ``PsiT, KU, KP, K3, D, pair``
    (:func:`sicomat.simulation.envelope.curvature_bounds`)."""
    return _kernel_layout([p.continuous for p in programs], programs[0].step,
                          levels if links.size else 0, links)


def sparse_outputs(CD: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``[C D]`` of every variant (shape (n_variants, ny, nx + nu)) as rows of a shared sparsity pattern.

    Returns ``(ptr, col, val)``: row ``r`` is ``Σ val[v, q] z[col[q]]`` for ``ptr[r] <= q < ptr[r+1]``;
    the pattern is the union of the variants' non-zeros (outputs are mostly selections of states).
    """
    mask = (CD != 0.0).any(axis=0) if CD.shape[0] > 1 else CD[0] != 0.0
    rows, col = np.nonzero(mask)
    ptr = np.zeros(CD.shape[1] + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=CD.shape[1]), out=ptr[1:])
    return ptr, col.astype(np.int64), np.ascontiguousarray(CD[:, rows, col])
