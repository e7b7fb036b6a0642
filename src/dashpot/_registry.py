"""What the package's registries (restitution laws, flight effects) share: removing an entry
added at run time, and read-only views computed anew from a registry on each access."""

from __future__ import annotations

from collections.abc import Mapping


class LiveMapping(Mapping):
    """A read-only mapping built by `items()` on each access, so that it follows a registry
    that changes at run time (an entry registered or removed)."""

    def __init__(self, items):
        self._items = items

    def __getitem__(self, key):
        return self._items()[key]

    def __iter__(self):
        return iter(self._items())

    def __len__(self):
        return len(self._items())


def unregister(registry, name, built_in, kind):
    """Remove `name`, an entry added at run time, from `registry` (a dict).

    Raises
    ------
    ValueError
        `name` is not registered, or is one of the `built_in` names (the modules' entries);
        the message names the `kind` of entry ("restitution law", "flight effect").
    """
    if name not in registry:
        raise ValueError(f"no {kind} {name!r} is registered")
    if name in built_in:
        raise ValueError(f"{kind} {name!r} is one of the built-in {kind}s")
    del registry[name]
