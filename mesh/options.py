"""Options of the geometry and meshing stage (scene sections [blade] and [mesh])."""
from __future__ import annotations

from dataclasses import dataclass

KNOWN_FORMATS = ("rotor67", "rotor37")
KNOWN_UNITS = {"ft": 0.3048, "in": 0.0254, "cm": 0.01, "mm": 0.001, "m": 1.0}
#: Senses of rotation: right-hand rule about the rotation axis (z), or the sense in which
#: the blade's leading edge leads (derived from the contact nodes' angles).
ROTATIONS = ("+", "-", "le-leads")


DEFAULT_GEOMETRY = "../../shared/data/rotor67/rotor67geometry.dat"
KNOWN_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class BladeOptions:
    """Which blade: a NASA geometry table meshed by bladerub, or the user's own mesh file.

    geometry: path of the NASA table, relative to the scene file (default: rotor 67's, when
        no mesh is given).
    format: table layout, one of KNOWN_FORMATS.
    units: length unit of the table or of the mesh file, one of KNOWN_UNITS. None for a
        table: the unit the table states in its text (rotor 67 "feet", rotor 37
        "centimeters"; mesh.geometry.stated_unit), since a fixed default fits one table
        only; a unit given must agree with that statement, and is needed for a table that
        states none. A mesh file must say its unit (a deck carries none).
    hub_section, tip_section: 1-based streamsurfaces of the table that bound the solid.
    mesh: path of a quadratic solid mesh (tet10, wedge15, hex20; .inp, .msh, .med, .bdf,
        .vtu, .xdmf...), relative to the scene file; excludes geometry. Read by
        mesh.imported.import_blade; format, hub_section and tip_section do not apply.
    axis: the mesh file's rotation axis through its origin, "x", "y" or "z" (mesh only).
    root: clamped nodes of the mesh file (mesh only): "boundary" = the nodes whose three
        translations the file fixes (*BOUNDARY of an .inp deck), "nset:NAME" = a node set
        of the file, "hub" = the nodes of the boundary faces that face the axis.
    contact_nodes: node ids as numbered in the mesh file, leading edge first (mesh only);
        None: [mesh] n_boundary nodes along the tip face, as for the tables. "As numbered":
        the file's own ids where the reader keeps them (an .inp deck's *NODE ids, a Nastran
        .bdf's GRID ids); for the other formats read through meshio (.msh, .med, .vtu,
        .xdmf, ...) the 1-based position of the node in the file's node list.
    rotation: sense of rotation, one of ROTATIONS: "+" or "-" (right-hand rule about the
      rotation axis (z of the product's frame; a mesh file's `axis`, turned onto z by a proper
      rotation): "+" turns the blade towards +theta), or
      "le-leads" (the default: the sense in which the leading edge is ahead of the trailing
      edge, as a compressor or fan blade turns; from the contact nodes' angles, see
      rom.rotation.rotation_sign). It decides where each contact node meets the casing
      lobes (eq. 28) and the direction of the sliding friction (eqs. 29-30).
    """

    geometry: str | None = None
    format: str = "rotor67"
    units: str | None = None
    hub_section: int = 1
    tip_section: int = 13
    mesh: str | None = None
    axis: str = "z"
    root: str = "boundary"
    contact_nodes: tuple[int, ...] | None = None
    rotation: str = "le-leads"

    def __post_init__(self):
        if self.mesh is not None and self.geometry is not None:
            raise ValueError(f"geometry ('{self.geometry}') and mesh ('{self.mesh}') are mutually exclusive: "
                             "give the table to mesh or the mesh file, not both")
        if self.mesh is None:
            if self.geometry is None:
                object.__setattr__(self, "geometry", DEFAULT_GEOMETRY)
            for key, value, default in (("axis", self.axis, "z"), ("root", self.root, "boundary"),
                                        ("contact_nodes", self.contact_nodes, None)):
                if value != default:
                    raise ValueError(f"{key} applies to a mesh file only ([blade] mesh); "
                                     "a geometry table is meshed with its own axis, root and contact nodes")
        else:
            if not self.mesh.strip():
                raise ValueError("mesh must name a mesh file")
            if self.units is None:
                raise ValueError(f"units is required with mesh: the length unit of '{self.mesh}', "
                                 f"one of {', '.join(KNOWN_UNITS)}")
            if self.axis not in KNOWN_AXES:
                raise ValueError(f"axis must be one of {', '.join(KNOWN_AXES)}, got '{self.axis}'")
            if not (self.root in ("boundary", "hub") or (self.root.startswith("nset:") and self.root[5:].strip())):
                raise ValueError(f"root must be \"boundary\", \"hub\" or \"nset:NAME\", got '{self.root}'")
            if self.contact_nodes is not None:
                ids = list(self.contact_nodes)
                if len(ids) < 2:
                    raise ValueError(f"contact_nodes needs at least 2 node ids (LE first), got {ids}")
                if len(set(ids)) != len(ids):
                    raise ValueError(f"contact_nodes lists a node twice: {ids}")
        if self.format not in KNOWN_FORMATS:
            raise ValueError(f"unknown geometry format '{self.format}'; known: {', '.join(KNOWN_FORMATS)}")
        if self.units is not None and self.units not in KNOWN_UNITS:
            raise ValueError(f"unknown length unit '{self.units}'; known: {', '.join(KNOWN_UNITS)}")
        if self.rotation not in ROTATIONS:
            raise ValueError(f"unknown rotation '{self.rotation}'; known: {', '.join(repr(r) for r in ROTATIONS)} "
                             "(right-hand rule about the rotation axis, or the sense in which the LE leads)")
        if not 1 <= self.hub_section < self.tip_section:
            raise ValueError(f"need 1 <= hub_section < tip_section, got {self.hub_section}, {self.tip_section}")

    @property
    def source(self) -> str:
        """The file the mesh stage reads: the mesh file, else the geometry table."""
        return self.mesh if self.mesh is not None else self.geometry


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
