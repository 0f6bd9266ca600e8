"""The identity cache behind every "kept for the last few objects" of the package."""

from __future__ import annotations

import gc

from rrt_pin.core.identity import IdentityCache


class Thing:
    """Equal to every other Thing: the cache must still tell them apart."""

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Thing)

    __hash__ = object.__hash__


def test_values_are_found_by_identity_not_equality():
    cache: IdentityCache[str] = IdentityCache(4)
    a, b = Thing(), Thing()
    assert a == b
    cache.put(a, value="a")
    assert cache.get(a) == "a" and cache.get(b) is None
    cache.put(a, b, value="ab")
    assert cache.get(a, b) == "ab" and cache.get(b, a) is None and cache.get(a) == "a"


def test_a_kept_object_stays_alive_so_its_id_is_never_another_objects():
    cache: IdentityCache[str] = IdentityCache(2)
    cache.put(Thing(), value="first")
    gc.collect()
    (key,) = cache._items  # noqa: SLF001 - the one entry's ids
    newcomer = Thing()
    assert (id(newcomer),) != key or cache.get(newcomer) is None
    assert cache.get(newcomer) is None


def test_the_least_recently_used_entry_goes_first():
    cache: IdentityCache[int] = IdentityCache(2)
    a, b, c = Thing(), Thing(), Thing()
    cache.put(a, value=1)
    cache.put(b, value=2)
    assert cache.get(a) == 1  # a is now the most recent
    cache.put(c, value=3)
    assert cache.get(b) is None and cache.get(a) == 1 and cache.get(c) == 3
    assert len(cache) == 2
    cache.clear()
    assert len(cache) == 0 and cache.get(a) is None
