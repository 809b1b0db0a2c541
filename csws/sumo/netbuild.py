"""Building SUMO networks: plain-XML text and one way to call netconvert.

The test tracks, the tests' small networks, the benchmarks' large ones and OSM
imports all go through :func:`netconvert`, so every network csws makes is built with
the same defaults: coordinates kept as authored (``--offset.disable-normalization``)
and no turnarounds at dead ends (``--no-turnarounds``).
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from csws.errors import CswsError
from csws.sumo.binaries import sumo_binary, sumo_home

__all__ = [
    "NetconvertError",
    "shape_text",
    "plain_xml_text",
    "required_attribute",
    "netconvert",
    "netconvert_osm",
    "netconvert_opendrive",
]

DEFAULT_OPTIONS = ("--no-turnarounds", "true", "--offset.disable-normalization", "true")


class NetconvertError(RuntimeError, CswsError):
    """netconvert failed, or (in strict mode) warned about its input."""


def shape_text(xy: np.ndarray) -> str:
    """A polyline as SUMO's ``x,y x,y ...`` with micrometre digits (netconvert rounds on output)."""
    return " ".join(f"{x:.6f},{y:.6f}" for x, y in np.asarray(xy, dtype=float))


def plain_xml_text(nodes: ElementTree.Element, edges: ElementTree.Element) -> tuple[str, str]:
    """The text of a plain-XML node file and edge file (netconvert's input) from their root elements."""
    return ElementTree.tostring(nodes, encoding="unicode"), ElementTree.tostring(edges, encoding="unicode")


def required_attribute(element: ElementTree.Element, name: str) -> str:
    """An attribute SUMO always writes on ``element`` (ValueError for a file that lacks it)."""
    value = element.get(name)
    if value is None:
        raise ValueError(f"a SUMO <{element.tag}> without {name!r}")
    return value


def netconvert(
    nodes_xml: str,
    edges_xml: str,
    net_file: str | Path,
    options: Sequence[str] = (),
    strict: bool = False,
) -> Path:
    """Write plain-XML nodes and edges and netconvert them into ``net_file``.

    Parameters
    ----------
    nodes_xml, edges_xml
        The ``<nodes>`` and ``<edges>`` documents.
    net_file
        Where the network goes.
    options
        netconvert options beyond :data:`DEFAULT_OPTIONS`.
    strict
        Treat any warning as an error: for networks whose geometry must be exactly as
        authored, a warning means netconvert changed or doubted the input.

    Raises
    ------
    NetconvertError
        With netconvert's messages, when it fails (or warns, in strict mode).
    """
    with tempfile.TemporaryDirectory(prefix="csws-plain-") as work:
        node_file, edge_file = Path(work) / "plain.nod.xml", Path(work) / "plain.edg.xml"
        node_file.write_text(nodes_xml, encoding="utf-8")
        edge_file.write_text(edges_xml, encoding="utf-8")
        inputs = ["--node-files", str(node_file), "--edge-files", str(edge_file)]
        return _run_netconvert([*inputs, *DEFAULT_OPTIONS, *options], net_file, strict)


def netconvert_osm(osm_files: Sequence[str | Path], net_file: str | Path, options: Sequence[str] = ()) -> Path:
    """Netconvert OpenStreetMap XML files (``.osm``, ``.osm.xml``, gzipped or not) into ``net_file``.

    Unlike plain XML, OSM coordinates are projected (UTM by default) and then moved to
    the origin as SUMO does; the ``<location>`` element keeps the offset and the
    projection so that lon/lat can be recovered. There are no turnarounds at dead ends,
    as for every csws network.

    Raises
    ------
    NetconvertError
        With netconvert's messages, when it fails. Warnings about the map data are
        expected on real extracts and are not errors.
    """
    inputs = ["--osm-files", ",".join(str(Path(path).resolve()) for path in osm_files)]
    return _run_netconvert([*inputs, "--no-turnarounds", "true", *options], net_file, strict=False)


def netconvert_opendrive(xodr_file: str | Path, net_file: str | Path, options: Sequence[str] = ()) -> Path:
    """Netconvert an ASAM OpenDRIVE file into ``net_file``, coordinates as authored and no turnarounds.

    Raises
    ------
    NetconvertError
        With netconvert's messages, when it fails (warnings about the road data are not errors).
    """
    inputs = ["--opendrive-files", str(Path(xodr_file).resolve())]
    return _run_netconvert([*inputs, *DEFAULT_OPTIONS, *options], net_file, strict=False)


def _run_netconvert(arguments: Sequence[str], net_file: str | Path, strict: bool) -> Path:
    """Run netconvert with ``arguments`` writing ``net_file``; raise :class:`NetconvertError` on failure."""
    net_file = Path(net_file).resolve()
    command = [str(sumo_binary("netconvert")), *arguments, "--output-file", str(net_file)]
    # PROJ_LIB: the projection data the wheel ships, for geo-referenced (OSM) networks.
    environment = {**os.environ, "SUMO_HOME": str(sumo_home()), "PROJ_LIB": str(sumo_home() / "data" / "proj")}
    result = subprocess.run(command, env=environment, capture_output=True, text=True)
    messages = (result.stdout + result.stderr).strip()
    warned = "warning" in messages.lower() or "error" in messages.lower()
    if result.returncode != 0 or (strict and warned):
        raise NetconvertError(f"netconvert failed on {net_file.name} (exit {result.returncode}):\n{messages}")
    return net_file
