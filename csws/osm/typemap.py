"""Road types for an OSM import: SUMO's type map, types for the highway values it does not
know, and the user's own type files.

netconvert keeps a way only if its ``highway`` value has a type in a type file; a value
it does not know is dropped without a word. Mapped data has such values: a tunnel or
a bridge tagged into the value (``primary_tunnel``, ``secondary_bridge``,
``motorway_link_tunnel``) instead of ``tunnel=yes``. Each such value built from a known
one (the known value, ``_`` and a suffix) gets a type of its own with the known type's
attributes, so the road is imported as the road it is, and its type name
(``highway.primary_tunnel``) keeps what the suffix said.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from xml.etree import ElementTree

from csws.sumo.binaries import sumo_home

__all__ = ["sumo_type_file", "known_highways", "base_highway", "derived_highways", "write_derived_types", "type_allows"]

HIGHWAY_PREFIX = "highway."


def sumo_type_file() -> Path:
    """SUMO's own type map for OSM imports."""
    return sumo_home() / "data" / "typemap" / "osmNetconvert.typ.xml"


def _types(path: Path) -> dict[str, ElementTree.Element]:
    """The ``<type>`` elements of a type file by id."""
    return {
        type_id: element for element in ElementTree.parse(path).getroot().iter("type") if (type_id := element.get("id"))
    }


def known_highways(type_files: Iterable[Path]) -> dict[str, ElementTree.Element]:
    """The ``highway`` values the type files give a type, with its element (later files win)."""
    known: dict[str, ElementTree.Element] = {}
    for path in type_files:
        for type_id, element in _types(path).items():
            if type_id.startswith(HIGHWAY_PREFIX):
                known[type_id[len(HIGHWAY_PREFIX) :]] = element
    return known


def base_highway(value: str, known: Iterable[str]) -> str | None:
    """The known value an unknown one is built from (the longest known ``v`` with ``value``
    starting ``v_``), or None."""
    bases = [candidate for candidate in known if value.startswith(candidate + "_")]
    return max(bases, key=len) if bases else None


def derived_highways(values: Iterable[str], known: Iterable[str]) -> dict[str, str]:
    """For each value the type files do not know but that is built from a known one: that one."""
    known = set(known)
    derived = {}
    for value in values:
        if value not in known and (base := base_highway(value, known)) is not None:
            derived[value] = base
    return derived


def write_derived_types(derived: dict[str, str], known: dict[str, ElementTree.Element], path: Path) -> Path:
    """Write a type file with a type for each derived value, copying its base type's attributes."""
    root = ElementTree.Element("types")
    for value, base in sorted(derived.items()):
        attributes = dict(known[base].attrib)
        attributes["id"] = HIGHWAY_PREFIX + value
        ElementTree.SubElement(root, "type", attributes)
    ElementTree.ElementTree(root).write(path, encoding="unicode", xml_declaration=False)
    return path


def type_allows(element: ElementTree.Element, vclasses: Iterable[str]) -> bool:
    """Whether a type lets one of ``vclasses`` drive: named in its ``allow``, or not in its ``disallow``."""
    vclasses = set(vclasses)
    if element.get("allow") is not None:
        return bool(vclasses & set(element.get("allow", "").split()))
    return not vclasses <= set(element.get("disallow", "").split())
