"""Gateways: the protocols vehicles and their terminals already speak, adapted to the engine.

A gateway turns a protocol's messages into fixes for :class:`csws.engine.Engine` (through the
same per-vehicle sessions as the HTTP service) and the engine's answers into the protocol's
messages back to the driver. Each protocol is a sub-package: :mod:`csws.gateways.jt808`.
"""
