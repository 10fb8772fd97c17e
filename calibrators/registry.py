"""The calibrator registry: built-ins register with ``@register``; installed packages add theirs
through the entry-point group ``magbench.calibrators`` (name = calibrator class)."""
from __future__ import annotations

from importlib import metadata

from magbench.errors import InputError

from .base import Calibrator
from .methods import BUILTINS

ENTRY_POINT_GROUP = "magbench.calibrators"

_REGISTRY: dict[str, type[Calibrator]] = {}
_plugins_loaded = False
_plugin_errors: dict[str, str] = {}


def register(cls: type) -> type:
    """Class decorator: add a calibrator under ``cls.name``.  A class that is not a ``Calibrator``, has no
    name, or takes a name already registered by another class is refused (``ValueError``) and the registry
    is left as it was."""
    if not (isinstance(cls, type) and issubclass(cls, Calibrator)):
        raise ValueError(f"{getattr(cls, '__qualname__', repr(cls))} is not a Calibrator subclass")
    name = getattr(cls, "name", "")
    if not name:
        raise ValueError(f"{cls.__name__} has no 'name'")
    if name in _REGISTRY and _REGISTRY[name] is not cls:
        raise ValueError(f"a calibrator named {name!r} is already registered "
                         f"({_REGISTRY[name].__module__}.{_REGISTRY[name].__qualname__})")
    _REGISTRY[name] = cls
    return cls


for _cls in BUILTINS:
    register(_cls)


def unregister(name: str) -> None:
    _REGISTRY.pop(name, None)


def _load_plugins() -> None:
    """Register the entry points of the group ``magbench.calibrators``.  A plug-in that fails to import,
    is not a Calibrator subclass, or would shadow a registered name is not registered; why is kept
    (``plugin_errors``) for ``magbench list`` and for ``--method NAME``."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        where = f"entry point {ep.name} = {ep.value}"
        try:
            cls = ep.load()
        except Exception as exc:  # a broken plug-in must not break the built-ins
            _plugin_errors[ep.name] = f"{where} failed to import: {type(exc).__name__}: {exc}"
            continue
        try:
            if isinstance(cls, type) and not getattr(cls, "name", ""):
                cls.name = ep.name  # type: ignore[attr-defined]  # checked by register() next
            register(cls)
        except ValueError as exc:
            _plugin_errors[ep.name] = f"{where} refused: {exc}"


def available() -> dict[str, type]:
    """All registered calibrators, built-in and plug-in, by name."""
    _load_plugins()
    return dict(_REGISTRY)


def plugin_errors() -> dict[str, str]:
    """Plug-ins that did not load, by entry-point name, with the reason."""
    available()
    return dict(_plugin_errors)


def get(name: str) -> type[Calibrator]:
    if not isinstance(name, str):
        raise InputError(f"a calibrator is named by a string (magbench list), not a {type(name).__name__}")
    calibrators = available()
    if name in calibrators:
        return calibrators[name]
    if name in _plugin_errors:
        raise InputError(f"calibrator {name!r} is unavailable: {_plugin_errors[name]}")
    raise InputError(f"unknown calibrator {name!r}; known: {', '.join(sorted(calibrators))}")


def make(name: str, **params):
    """Instantiate a registered calibrator with hyper-parameters."""
    cls = get(name)
    cls.check_param_names(params)
    cls.check_param_values(params)
    return cls(**params)
