"""Options of the geometry and meshing stage (scene sections [blade] and [mesh])."""
from __future__ import annotations

from dataclasses import dataclass

KNOWN_FORMATS = ("rotor67", "rotor37")
KNOWN_UNITS = {"ft": 0.3048, "in": 0.0254, "cm": 0.01, "mm": 0.001, "m": 1.0}


@dataclass(frozen=True)
class BladeOptions:
    """Which blade, from which table.

    geometry: path of the NASA table, relative to the scene file.
    format: table layout, one of KNOWN_FORMATS.
    units: length unit of the table, one of KNOWN_UNITS (rotor 67: "ft").
    hub_section, tip_section: 1-based streamsurfaces that bound the solid.
    """

    geometry: str = "../../shared/data/rotor67/rotor67geometry.dat"
    format: str = "rotor67"
    units: str = "ft"
    hub_section: int = 1
    tip_section: int = 13

    def __post_init__(self):
        if self.format not in KNOWN_FORMATS:
            raise ValueError(f"unknown geometry format '{self.format}'; known: {', '.join(KNOWN_FORMATS)}")
        if self.units not in KNOWN_UNITS:
            raise ValueError(f"unknown length unit '{self.units}'; known: {', '.join(KNOWN_UNITS)}")
        if not 1 <= self.hub_section < self.tip_section:
            raise ValueError(f"need 1 <= hub_section < tip_section, got {self.hub_section}, {self.tip_section}")


@dataclass(frozen=True)
class MeshOptions:
    """Meshing parameters.

    element_size: target edge length of the quadratic tetrahedra away from the edges, m.
    n_boundary: number of tip boundary (contact) nodes, leading to trailing edge.
    edge_layers: elements across the blade thickness at the leading and trailing edges;
        the size on the LE/TE lines is the thinnest edge thickness of the table divided by
        this number (capped at element_size).
    size_growth: slope of the element size with distance from the LE/TE lines (m/m): the
        size grows linearly from the edge size to element_size.
    """

    # Defaults: about 200 000 nodes for rotor 67 (the paper's mesh has 201 287). A coarse
    # mesh for fast runs (~24 000 nodes): element_size = 0.008, edge_layers = 1, size_growth = 0.5.
    element_size: float = 0.00145
    n_boundary: int = 9
    edge_layers: int = 2
    size_growth: float = 0.3

    def __post_init__(self):
        if not self.element_size > 0:
            raise ValueError(f"element_size must be > 0 m, got {self.element_size}")
        if self.n_boundary < 2:
            raise ValueError(f"n_boundary must be >= 2, got {self.n_boundary}")
        if self.edge_layers < 1:
            raise ValueError(f"edge_layers must be >= 1, got {self.edge_layers}")
        if not self.size_growth > 0:
            raise ValueError(f"size_growth must be > 0, got {self.size_growth}")
