"""Registries of the pluggable blocks ("Modify Scheme", paper III): per block *kind*, the schema classes
keyed by the model file's ``type``.

A kind (``"mechanics"``, ``"setpoint"``) is a table of the model file (``[axes.X.mechanics]``,
``[axes.X.trajectory]``) whose ``type`` key chooses the class that reads it. A new type is one class with
a ``type: Literal["name"]`` field and one :func:`register` decorator, in a module that is imported before
the kind's union is built (:func:`spec_union`): ``description/mechanics.py`` or ``description/shorthands.py``
for mechanics (the union is built in ``description/machine.py``), ``description/motion.py`` for setpoints.
Everything else follows from the registry: the model file's discriminated union, the loader's error
messages, the conformance suite ``tests/test_block_kinds.py``. See ``docs/blocks.md``.

What a registered class must provide is its kind's protocol: :class:`MechanicsKind` (``to_lumped()``,
then the one :func:`sicomat.mechanics.lumped.build_mechanics`) or :class:`SetpointKind` (the lowering to
a profile is :func:`sicomat.motion.setpoints.profile_from_spec`, which sits beside the description).

Examples
--------
>>> registered_types("mechanics")
('lumped', 'chain', 'belt-rack', 'components')
>>> spec_class("setpoint", "s-curve").__name__
'SCurveSetpoint'
"""

from __future__ import annotations

import typing
from typing import TYPE_CHECKING, Annotated, Any, Callable, Generic, Protocol, TypeVar, Union, runtime_checkable

from pydantic import Field

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from .mechanics import LumpedSpec

__all__ = ["Registry", "KINDS", "MechanicsKind", "SetpointKind", "register", "spec_class", "registered_types", "spec_union",
           "union_tags"]


@runtime_checkable
class MechanicsKind(Protocol):
    """A mechanical structure: any description that lowers to the general lumped form."""

    @property
    def type(self) -> str: ...  # the model file's ``type`` (a Literal on each class)

    def to_lumped(self) -> "LumpedSpec":
        """The same mechanics as a :class:`~sicomat.description.mechanics.LumpedSpec`."""
        ...  # pragma: no cover


@runtime_checkable
class SetpointKind(Protocol):
    """A setpoint generator of one axis: a move that begins at ``start`` (s).

    Its one lowering, to a piecewise-polynomial profile (``evaluate(t) -> (position, velocity,
    acceleration)``, ``distance``, ``end_time``), is registered beside it in
    :mod:`sicomat.motion.setpoints` (the description never imports the runtime).
    """

    @property
    def type(self) -> str: ...  # the model file's ``type`` (a Literal on each class)

    @property
    def start(self) -> float: ...


KINDS: dict[str, tuple[str, type]] = {
    "mechanics": ("mechanics", MechanicsKind),
    "setpoint": ("trajectory", SetpointKind),
}
"""The block kinds with a registry: kind → (key of its table under ``[axes.<name>]``, protocol)."""

_TYPES: dict[str, dict[str, type]] = {kind: {} for kind in KINDS}
_SEALED: set[str] = set()

T = TypeVar("T", bound=type)


def _literal_type(cls: type) -> str | None:
    field = getattr(cls, "model_fields", {}).get("type")
    if field is None:
        return None
    args = typing.get_args(field.annotation)
    return args[0] if typing.get_origin(field.annotation) is typing.Literal and len(args) == 1 else None


def register(kind: str, type_name: str | None = None) -> Callable[[T], T]:
    """Class decorator: ``cls`` reads the ``kind`` table whose ``type`` is ``type_name``.

    ``type_name`` defaults to the class's ``type: Literal[...]`` field (and must equal it when
    given). Registration order is the order of the union (and of the "expected one of" lists).

    Raises
    ------
    ValueError
        Unknown kind, a class without a one-value ``type`` literal or without the kind's protocol, a
        type registered twice, or a registration after the kind's union was built (it would be
        known here but refused by the model file).
    """
    if kind not in KINDS:
        raise ValueError(f"unknown block kind {kind!r}; expected one of {', '.join(KINDS)}")

    def decorate(cls: T) -> T:
        name = _literal_type(cls)
        if name is None or (type_name is not None and name != type_name):
            raise ValueError(f"{cls.__name__} needs a field type: Literal[{type_name or '...'!r}]")
        if name in _TYPES[kind]:
            raise ValueError(f"{kind} type {name!r} is already registered by {_TYPES[kind][name].__name__}")
        protocol = KINDS[kind][1]
        missing = [m for m, v in vars(protocol).items()
                   if callable(v) and not m.startswith("_") and not callable(getattr(cls, m, None))]
        if missing:
            raise ValueError(f"{cls.__name__} lacks {', '.join(missing)}() of the {kind} protocol")
        if kind in _SEALED:
            raise ValueError(f"the {kind} union is already built; register {cls.__name__} in a module "
                             "imported before it (see sicomat.description.registry)")
        _TYPES[kind][name] = cls
        return cls

    return decorate


def registered_types(kind: str) -> tuple[str, ...]:
    """The registered ``type`` names of ``kind``, in registration order."""
    return tuple(_TYPES[kind])


def spec_class(kind: str, type_name: Any, *, source: str | None = None, path: str | None = None) -> type:
    """The schema class of ``kind`` for ``type_name``.

    Raises
    ------
    ModelError
        ``type_name`` is not registered: the message names ``path`` (default: the kind's table key)
        and lists the known types, as the model-file loader does.
    """
    try:
        return _TYPES[kind][type_name]
    except (KeyError, TypeError):
        known = ", ".join(repr(t) for t in _TYPES[kind])
        raise ModelError(f"unknown type; expected one of {known}", source=source,
                         path=path or KINDS[kind][0], value=type_name, has_value=True) from None


def spec_union(kind: str) -> Any:
    """The pydantic discriminated union (on ``type``) of every class registered for ``kind``; the
    kind is closed from then on (see :func:`register`)."""
    classes = tuple(_TYPES[kind].values())
    if not classes:
        raise ValueError(f"no {kind} type is registered")
    _SEALED.add(kind)
    member = classes[0] if len(classes) == 1 else Union[classes]
    return Annotated[member, Field(discriminator="type")]


def union_tags() -> dict[str, tuple[str, ...]]:
    """Table key under ``[axes.<name>]`` → its registered types (the model-file loader's error messages)."""
    return {key: registered_types(kind) for kind, (key, _) in KINDS.items()}


# --------------------------------------------------------------------------- run-time side
K = TypeVar("K")


class Registry(Generic[K]):
    """The run-time side of a block kind: what each model-file ``type`` lowers to (the servo's drive and
    controller kinds, the setpoint lowerings of :mod:`sicomat.motion.setpoints`), in registration order.
    The schema side is :func:`register` above; both are keyed by the same ``type`` strings.

    >>> from sicomat.servo.blocks import CONTROLLERS, controller_kind
    >>> CONTROLLERS.types()
    ('P-PI', 'P-IP', 'P-TF')
    >>> controller_kind("P-ID", path="axes.X.controller.type")
    Traceback (most recent call last):
    ...
    sicomat.errors.ModelError: axes.X.controller.type: unknown controller type; known types: P-PI, P-IP, P-TF (got 'P-ID')
    """

    def __init__(self, block: str) -> None:
        self.block = block
        self._kinds: dict[str, K] = {}

    def register(self, cls: Callable[[], K]) -> Callable[[], K]:
        """Class decorator: register one instance of ``cls`` under its ``type``."""
        kind = cls()
        name = getattr(kind, "type")
        if name in self._kinds:
            raise ValueError(f"{self.block} type {name!r} is registered twice")  # pragma: no cover
        self._kinds[name] = kind
        return cls

    def add(self, name: str, item: K) -> K:
        """Register ``item`` (a lowering function, say) under the type ``name``."""
        if name in self._kinds:
            raise ValueError(f"{self.block} type {name!r} is registered twice")
        self._kinds[name] = item
        return item

    def get(self, name: str) -> K | None:
        """The item registered as ``name``, or None."""
        return self._kinds.get(name)

    def lookup(self, name: str, *, path: str | None = None, source: str | None = None) -> K:
        """The kind registered as ``name``; a located :class:`~sicomat.errors.ModelError` naming the
        known types otherwise."""
        try:
            return self._kinds[name]
        except (KeyError, TypeError):
            raise ModelError(f"unknown {self.block} type; known types: {', '.join(self._kinds)}",
                             source=source, path=path, value=name) from None

    def types(self) -> tuple[str, ...]:
        """The registered types, in registration order."""
        return tuple(self._kinds)

    def kinds(self) -> tuple[K, ...]:
        return tuple(self._kinds.values())
