"""The calibrator registry: built-ins register with ``@register``; installed packages add theirs
through the entry-point group ``magbench.calibrators`` (name = calibrator class)."""
from __future__ import annotations

from importlib import metadata

from magbench.errors import InputError

ENTRY_POINT_GROUP = "magbench.calibrators"

_REGISTRY: dict[str, type] = {}
_plugins_loaded = False
_plugin_errors: dict[str, str] = {}


def register(cls: type) -> type:
    """Class decorator: add a calibrator under ``cls.name``; a second class with the same name is refused."""
    name = getattr(cls, "name", "")
    if not name:
        raise ValueError(f"{cls.__name__} has no 'name'")
    if name in _REGISTRY and _REGISTRY[name] is not cls:
        raise ValueError(f"a calibrator named {name!r} is already registered "
                         f"({_REGISTRY[name].__module__}.{_REGISTRY[name].__qualname__})")
    _REGISTRY[name] = cls
    return cls


def unregister(name: str) -> None:
    _REGISTRY.pop(name, None)


def _load_plugins() -> None:
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            cls = ep.load()
            if not getattr(cls, "name", ""):
                cls.name = ep.name
            register(cls)
        except Exception as exc:  # a broken plug-in must not break the built-ins
            _plugin_errors[ep.name] = f"{type(exc).__name__}: {exc}"


def available() -> dict[str, type]:
    """All registered calibrators, built-in and plug-in, by name."""
    from . import builtin  # noqa: F401  (registers the built-ins)

    _load_plugins()
    return dict(_REGISTRY)


def plugin_errors() -> dict[str, str]:
    available()
    return dict(_plugin_errors)


def get(name: str) -> type:
    calibrators = available()
    try:
        return calibrators[name]
    except KeyError:
        raise InputError(f"unknown calibrator {name!r}; known: {', '.join(sorted(calibrators))}") from None


def make(name: str, **params):
    """Instantiate a registered calibrator with hyper-parameters."""
    cls = get(name)
    cls.check_param_names(params)
    return cls(**params)
