"""Decides where a road continues through a junction, and where a path leaves it, for the road chains.

A road is a chain of edges through the nodes where it continues: a way split, a side
road joining, the straight-ahead or priority continuation at a crossing. A curve of the
road is a curve whole, whatever node lies inside it; only a turn from one road into
another (the path leaves the chain at a junction) and a drive round a roundabout are
junction manoeuvres without curvature points of interest (see ``docs/junctions.md``).

At each node, an incoming edge ``i`` and an outgoing edge ``o`` continue one road when
each is the other's best partner among the edges connected to it (a "mutual best fit",
as street networks are usually joined into strokes):

1. a U-turn (SUMO direction ``t``) never continues a road;
2. an edge with a single partner continues into it, whatever the angle: a way split or
   a node inside a bend, where the road can only go on;
3. among several partners, the one with the same street name comes first, then the one
   of the nearest priority (a minor road crossing a major one goes on as itself; a major
   road goes on as itself past a minor one joining inside its bend), then the same road
   type, then the smallest change of heading; a partner that turns by more than :data:`MAX_CONTINUATION_DEFLECTION_DEG`
   is then no continuation of the road but a turn.
"""

from __future__ import annotations

import math
from collections import defaultdict

import sumolib

__all__ = ["MAX_CONTINUATION_DEFLECTION_DEG", "road_continuations"]

#: Where an edge has several partners at a node, the road continues only into one that
#: turns by at most this much, degrees. Across a junction a bend of the road turns by the
#: junction's size over its radius (15 m across a 30 m hairpin: 29 degrees); a turn into
#: a side street turns by 60 to 120 degrees.
MAX_CONTINUATION_DEFLECTION_DEG = 60.0


def _heading_rad(shape: list[tuple[float, float]], end: int) -> float:
    """Heading of a lane shape's first (``end=0``) or last (``end=-1``) segment, radians."""
    (x0, y0), (x1, y1) = (shape[0], shape[1]) if end == 0 else (shape[-2], shape[-1])
    return math.atan2(y1 - y0, x1 - x0)


def _deflection_deg(connection: sumolib.net.connection.Connection) -> float:
    """How much a connection turns, from the end of its lane to the start of the next, degrees."""
    turn = _heading_rad(connection.getToLane().getShape(), 0) - _heading_rad(connection.getFromLane().getShape(), -1)
    return abs(math.degrees(math.remainder(turn, 2.0 * math.pi)))


def _edge_pairs(net: sumolib.net.Net) -> dict[tuple[str, str], float]:
    """Every pair of normal edges joined by a connection other than a U-turn, with its
    smallest deflection over the connections of their lanes, degrees."""
    pairs: dict[tuple[str, str], float] = {}
    for edge in net.getEdges():
        if edge.getFunction() != "":
            continue
        for lane in edge.getLanes():
            for connection in lane.getOutgoing():
                following = connection.getTo()
                if following.getFunction() != "" or connection.getDirection() == "t":
                    continue
                key = (edge.getID(), following.getID())
                pairs[key] = min(pairs.get(key, math.inf), _deflection_deg(connection))
    return pairs


def _preference(me: sumolib.net.edge.Edge, partner: sumolib.net.edge.Edge, deflection_deg: float) -> tuple:
    """Sort key of a partner edge: same name, then the nearest priority, then same type, then least turning."""
    return (
        not (me.getName() and partner.getName() == me.getName()),
        abs(partner.getPriority() - me.getPriority()),
        not (me.getType() and partner.getType() == me.getType()),
        deflection_deg,
    )


def _best_partners(net: sumolib.net.Net, pairs: dict[tuple[str, str], float], side: int) -> dict[str, tuple[str, bool]]:
    """For each edge on one side of the pairs (0: incoming, 1: outgoing), its best partner on the
    other side and whether it had a choice."""
    partners: dict[str, list[str]] = defaultdict(list)
    for pair in pairs:
        partners[pair[side]].append(pair[1 - side])
    best = {}
    for edge_id, candidates in partners.items():
        me = net.getEdge(edge_id)
        ranked = [
            (_preference(me, net.getEdge(other), pairs[_pair(edge_id, other, side)]), other) for other in candidates
        ]
        best[edge_id] = (min(ranked, key=lambda entry: entry[0])[1], len(candidates) > 1)
    return best


def _pair(edge_id: str, other: str, side: int) -> tuple[str, str]:
    """The pair ``(incoming, outgoing)`` of an edge on ``side`` (0: incoming, 1: outgoing) and its partner."""
    return (edge_id, other) if side == 0 else (other, edge_id)


def road_continuations(net: sumolib.net.Net) -> frozenset[tuple[str, str]]:
    """The pairs ``(incoming edge, outgoing edge)`` that continue one road through their node.

    Parameters
    ----------
    net
        A SUMO network read by sumolib.

    Returns
    -------
    frozenset[tuple[str, str]]
        Edge id pairs; a connection between edges of no such pair is a turn into another road.
    """
    pairs = _edge_pairs(net)
    best_out = _best_partners(net, pairs, 0)
    best_in = _best_partners(net, pairs, 1)
    continuing = set()
    for (incoming, outgoing), deflection_deg in pairs.items():
        out_choice, in_had_choice = best_out[incoming]
        in_choice, out_had_choice = best_in[outgoing]
        if out_choice != outgoing or in_choice != incoming:
            continue
        if (in_had_choice or out_had_choice) and deflection_deg > MAX_CONTINUATION_DEFLECTION_DEG:
            continue
        continuing.add((incoming, outgoing))
    return frozenset(continuing)
