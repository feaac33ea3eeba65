"""The model: an immutable description of a machine (no matrices yet).

A :class:`Model` is built by :func:`chatterlab.load_model` from a TOML model
file (see ``docs/model-format.md``) or in Python.  Every item is a frozen
dataclass; a changed parameter is a new model (:meth:`Model.with_parameter`),
which is what makes parallel sweeps safe.

All quantities are SI: m, kg, kg m^2, N/m, N m/rad, N s/m, s, rad.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..errors import MAX_DELAY

__all__ = [
    "Body",
    "Node",
    "Section",
    "Beam",
    "PointRef",
    "Point",
    "Spring",
    "Attachment",
    "Support",
    "Contact",
    "Constraint",
    "Coupling",
    "Process",
    "tooth_period",
    "spindle_speed_for",
    "stroke_cycle",
    "stroke_speed",
    "cutting_speed",
    "ProcessDamping",
    "Movable",
    "Machine",
    "machine_problem",
    "MatrixBlock",
    "Model",
    "DIRECTIONS",
    "GROUND",
]

#: Names of the three plane coordinates of a body, node or point.
DIRECTIONS: tuple[str, str, str] = ("x", "y", "rz")

#: spindle speeds accepted, rpm: beyond them the tooth period over- or
#: underflows the Floquet meshes (1e-300 rpm: a period of 1e301 s; 1e300 rpm:
#: 1e-299 s).  Real spindles run 10..200000 rpm (the CLI warns outside that); the model reader and
#: :func:`chatterlab.process.check_spindle_speed` refuse outside SPEED_RANGE.
SPEED_RANGE = (0.1, 1e7)
#: the plausible spindle speeds, rpm, named in the messages
SPEED_PLAUSIBLE = (10.0, 2e5)
#: the largest helix angle accepted, deg: end mills have up to about 60 deg;
#: near 90 deg the flute wraps the tool without bound (tan(beta) -> inf)
HELIX_MAX_DEG = 85.0
#: Id of the immovable foundation (its coordinates are given, q_g = 0).
GROUND = "ground"


@dataclass(frozen=True)
class Body:
    """Rigid finite element (RFE): mass, rotary inertia about Z, centre.

    ``mass == 0`` (a massless body) is allowed only when all three of its
    coordinates are dependent (a :class:`Contact`, or a constraint).
    """

    id: str
    mass: float
    inertia: float
    centre: tuple[float, float]
    angle: float = 0.0  #: orientation of the body axes, rad
    movable: bool = False  #: part of the movable subsystem


@dataclass(frozen=True)
class Node:
    """A beam node at ``xy`` (m)."""

    id: str
    xy: tuple[float, float]
    movable: bool = False


@dataclass(frozen=True)
class Section:
    """Material and cross-section of a beam (SI)."""

    E: float  #: Young's modulus, Pa
    G: float  #: shear modulus, Pa
    rho: float  #: density, kg/m^3
    A: float  #: area, m^2
    I: float  #: second moment of area about the bending axis, m^4
    kappa: float = 5.0 / 6.0  #: Timoshenko shear coefficient
    eta: float = 0.0  #: internal (Kelvin-Voigt) damping coefficient, N s/m^2


@dataclass(frozen=True)
class Beam:
    """Deformable finite element (DFE): a plane Timoshenko beam between two
    nodes, optionally subdivided into ``elements`` equal elements."""

    id: str
    nodes: tuple[str, str]
    section: Section
    elements: int = 1


@dataclass(frozen=True)
class PointRef:
    """Where a point is: on a body, a node, a beam, the ground, or (for a
    matrix-level model) on named coordinates.

    ``kind``/``target`` say on what; ``offset`` is (dx, dy) in body axes for a
    body or node, and (0, transverse offset) for a beam, with ``distance``
    along the beam from its first node.  For ``kind == "coords"``, ``coords``
    names the coordinate carrying x, y and rz (``""`` for none).
    """

    kind: Literal["body", "node", "beam", "ground", "coords"]
    target: str
    offset: tuple[float, float] = (0.0, 0.0)
    distance: float = 0.0
    coords: tuple[str, str, str] = ("", "", "")
    label: str = ""  #: how the user wrote it, for messages
    #: modal models: per direction (x, y, rz) the modal coordinates and shape
    #: entries that make up the physical coordinate named in ``coords``
    weights: tuple[tuple[tuple[str, float], ...], ...] = ()


@dataclass(frozen=True)
class Point:
    """A named point, usable in springs, couplings and as FRF input/output."""

    id: str
    ref: PointRef


@dataclass(frozen=True)
class Spring:
    """Spring-damping element (SDE) between two coincident points.

    Stiffness ``c = (c1, c2, c6)`` (N/m, N/m, N m/rad) and damping
    ``d = (d1, d2, d6)`` (N s/m, N s/m, N m s/rad) along the element axes,
    which are rotated by ``angle`` (rad) from the global axes.
    """

    id: str
    a: PointRef
    b: PointRef
    c: tuple[float, float, float]
    d: tuple[float, float, float] = (0.0, 0.0, 0.0)
    angle: float = 0.0


@dataclass(frozen=True)
class Attachment:
    """A beam node clamped to a body through a rigid arm: the node's
    coordinates become dependent on the body's (or given, for the ground)."""

    id: str
    node: str
    body: str


@dataclass(frozen=True)
class Support:
    """Given (prescribed, q_g = 0) coordinates of a node or body."""

    id: str
    target: str
    dofs: tuple[str, ...]


@dataclass(frozen=True)
class Contact:
    """A massless moving contact point (the paper's RFE 5 and 6).

    Its coordinates are dependent: they equal the motion of the material
    point of a beam track (a chain of collinear beams) at transverse
    ``offset`` and at the along-track position of the moving ``follows``
    body's centre plus ``shift``.  The position therefore changes with the
    configuration parameter s, and so does W(s) (Eq. 2.7).
    """

    id: str
    beams: tuple[str, ...]
    follows: str
    offset: float = 0.0
    shift: float = 0.0
    outside: Literal["error", "clamp"] = "error"  #: beyond the track: refuse, or wait at its end


@dataclass(frozen=True)
class Constraint:
    """General linear constraints (Eq. 2.4): ``sum_k a_k q_k = 0`` for each
    equation; ``dependent`` lists the coordinates they determine."""

    id: str
    dependent: tuple[str, ...]
    equations: tuple[tuple[tuple[str, float], ...], ...]


@dataclass(frozen=True)
class Coupling:
    """Coupling element (CE): the feedback of the cutting process (Eq. 3.5).

    The force the CE applies to point ``a`` (the tool), in the CE axes rotated
    by ``angle`` from global, is

        P_a = (b / width_ref) [P0 - D_V dw/dt - D_P dw - D_O dw(t - T)],

    with dw = w_a - w_b the relative displacement of the two points in CE
    axes; point ``b`` receives -P_a.  The matrices are at the reference width
    ``width_ref`` and scale linearly with the width of cut b.  ``kind`` records
    how they were given (``"matrices"``, ``"grasso"`` for the K1..K8 of the
    paper's Table 3, ``"regenerative"`` for K_f b (h(t) - h(t - T))).
    """

    id: str
    a: PointRef
    b: PointRef
    DP: tuple[tuple[float, ...], ...]
    DV: tuple[tuple[float, ...], ...]
    DO: tuple[tuple[float, ...], ...]
    width_ref: float
    forces: tuple[float, float, float] = (0.0, 0.0, 0.0)
    angle: float = 0.0
    kind: str = "matrices"
    params: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class MillingCut:
    """The cutter and the cut of a milling process (``[process] kind =
    "milling"``), SI units and radians.  The analyses turn it into
    :class:`chatterlab.process.Milling` (periodic directional matrices,
    delays, the zeroth-order average that the ``model = "milling"`` coupling
    feeds to the frequency-domain engines).

    Angles follow Insperger & Stepan (2004): a tooth's angle phi is measured
    from +y, clockwise towards +x (the feed direction, CE axis 1);
    down-milling exits at phi = pi.
    """

    teeth: int
    diameter: float  #: m
    Kt: float  #: tangential cutting-force coefficient, N/m^2
    Kn: float  #: normal (radial) cutting-force coefficient, N/m^2
    entry: float  #: rad
    exit: float  #: rad
    pitch: tuple[float, ...] = ()  #: rad, one per tooth (sum 2 pi); () uniform
    helix: float = 0.0  #: rad
    Kte: float = 0.0  #: N/m
    Kne: float = 0.0  #: N/m
    runout: tuple[float, ...] = ()  #: radial offset of each tooth, m (time domain only)
    feed_per_tooth: float = 0.0  #: f_z, m (time domain only: the static chip)


# ---------------------------------------------------------------- speed <-> delay
# The one place where a speed becomes a delay (and back): the process
# kinematics of Process below and of chatterlab.process.Milling use these.


def tooth_period(rpm: Any, teeth: int = 1) -> Any:
    """T = 60 / (N n), s: the time between two teeth (turning: N = 1, one
    revolution) at n rpm."""
    return 60.0 / (teeth * rpm)


def spindle_speed_for(T: Any, teeth: int = 1) -> Any:
    """n = 60 / (N T), rpm: the inverse of :func:`tooth_period`."""
    return 60.0 / (teeth * T)


def stroke_cycle(stroke: Any, speed: Any, return_speed: Any) -> Any:
    """T = L / v_w + L / v_l, s: one stroke cycle of a shaper (work stroke of
    length L at v_w, return at v_l): the delay between two passes."""
    return stroke / speed + stroke / return_speed


def stroke_speed(stroke: Any, T: Any, return_speed: Any) -> Any:
    """v_w = L / (T - L / v_l), m/s: the inverse of :func:`stroke_cycle`."""
    return stroke / (T - stroke / return_speed)


def cutting_speed(rpm: Any, diameter: float) -> Any:
    """V = pi D n / 60, m/s: the surface speed of a spindle turning at n rpm
    at the diameter D (m): the workpiece's in turning, the cutter's in
    milling (a shaper's cutting speed is its work speed itself)."""
    return np.pi * diameter * rpm / 60.0


@dataclass(frozen=True)
class Process:
    """Process kinematics: how the cutting speed sets the delay T.

    ``kind``:

    * ``"shaping"``: stroke = run_in + cut + coast (m), work speed v_w and
      return speed v_l (m/s); T = stroke/v_w + stroke/v_l (one stroke cycle).
      The speed variable is v_w in m/s.
    * ``"turning"``: spindle speed n (rpm); T = 60/n.  Speed variable: rpm.
    * ``"delay"``: T given directly (s).
    * ``"milling"``: spindle speed n (rpm); T = 60/(N n), the tooth period
      (for a variable pitch the mean one: each tooth's own delay is
      pitch_j / Omega, see :class:`chatterlab.process.Milling`); the cutter
      and the cut are in ``milling``.
    """

    kind: Literal["shaping", "turning", "delay", "milling"]
    speed: float = 0.0  #: the default value of the speed variable
    delay_value: float = 0.0
    run_in: float = 0.0
    cut: float = 0.0
    coast: float = 0.0
    return_speed: float = 0.0
    start: float = 0.0  #: slide position s at the start of the work stroke, m
    direction: float = -1.0  #: +1 / -1: s increases / decreases in the work stroke
    milling: MillingCut | None = None

    @property
    def speed_unit(self) -> str:
        return {"shaping": "m/s", "turning": "rpm", "delay": "s", "milling": "rpm"}[self.kind]

    @property
    def speed_name(self) -> str:
        names = {
            "shaping": "work speed",
            "turning": "spindle speed",
            "delay": "delay",
            "milling": "spindle speed",
        }
        return names[self.kind]

    def delay(self, speed: float | np.ndarray | None = None) -> float | np.ndarray:
        """Delay T (s) at the given speed (in :attr:`speed_unit`)."""
        v = self.speed if speed is None else speed
        v = np.asarray(v, dtype=float)
        if speed is not None and not np.all(np.isfinite(v) & (v > 0)):
            # the one speed check (chatterlab.errors.check_speed) on the first bad value:
            # a speed <= 0 would give a negative or infinite delay, never a result
            from ..errors import check_speed

            bad = v[~(np.isfinite(v) & (v > 0))] if v.ndim else v
            check_speed(float(np.ravel(bad)[0]), "speed", self.speed_unit)
        if self.kind == "shaping":
            out = stroke_cycle(self.stroke, v, self.return_speed)
        elif self.kind in ("turning", "milling"):
            out = tooth_period(v, self._teeth)
        else:
            out = v if speed is not None else np.asarray(self.delay_value)
        if speed is not None and np.any(out > MAX_DELAY):
            from ..errors import check_delay

            check_delay(float(np.max(out)), f"the delay at this speed ({self.speed_name})")
        return float(out) if out.ndim == 0 else out

    def speed_for_delay(self, T: float | np.ndarray) -> float | np.ndarray:
        """Inverse of :meth:`delay`: the speed that gives the delay T."""
        T = np.asarray(T, dtype=float)
        if self.kind == "shaping":
            out = stroke_speed(self.stroke, T, self.return_speed)
        elif self.kind in ("turning", "milling"):
            out = spindle_speed_for(T, self._teeth)
        else:
            out = T
        return float(out) if out.ndim == 0 else out

    @property
    def _teeth(self) -> int:
        return self.milling.teeth if self.milling is not None else 1

    @property
    def stroke(self) -> float:
        """Shaping: run-in + cut + coast, m (0 for the other kinds)."""
        return self.run_in + self.cut + self.coast

    @property
    def min_delay(self) -> float:
        """The smallest delay any speed can give (the return-stroke time for
        shaping, 0 otherwise)."""
        if self.kind == "shaping":
            return self.stroke / self.return_speed
        return 0.0

    @property
    def width_name(self) -> str:
        """What the width of cut is called: the axial depth a_p for milling."""
        return "axial depth of cut a_p" if self.kind == "milling" else "width of cut b"

    @property
    def limit_name(self) -> str:
        """The symbol of the stability limit: a_lim for milling, b_lim otherwise."""
        return "a_lim" if self.kind == "milling" else "b_lim"


#: the spindle-speed variation's wave shapes (``[ssv] shape``)
SSV_SHAPES = ("sine", "triangle")
#: the largest relative amplitude RVA: the speed 1 - RVA of its mean stays well above 0
#: (a spindle that stops has no delay); programs use 0.05..0.3
SSV_AMPLITUDE_MAX = 0.9
#: the relative frequencies RVF accepted: from a variation over 1e5 revolutions (which no
#: discretisation resolves) to ten per revolution (a spindle follows at most ~1 per revolution)
SSV_FREQUENCY_RANGE = (1e-5, 10.0)


@dataclass(frozen=True)
class SpindleSpeedVariation:
    """A spindle-speed variation program (``[ssv]``, docs/ssv.md): the speed
    Omega(t) = Omega_0 [1 + rva S(rvf Omega_0 t)] about the mean speed, S the
    unit ``shape`` (sine or triangle); rva and rvf are ratios (1).  The analysis
    takes it as :class:`chatterlab.process.SpeedVariation`."""

    rva: float
    rvf: float
    shape: str = "sine"


@dataclass(frozen=True)
class Machine:
    """The limits of the machine and its tool that a recommended cut must
    respect, and the feed of the cut (``[machine]``, docs/model-format.md;
    the analysis is :func:`chatterlab.selection.recommend`).  Every field
    is optional: an absent limit does not limit.

    Speeds are in the process's speed unit (rpm for turning and milling,
    m/s for a shaper's work speed), everything else SI.  A curve is a tuple
    of (speed, value) points with the speeds strictly increasing, read
    linearly between them; a curve of one point is that value at every
    speed.
    """

    max_speed: float = float("inf")  #: the spindle's (or the ram's) highest speed
    min_speed: float = 0.0  #: its lowest speed
    power: tuple[tuple[float, float], ...] = ()  #: (speed, W): the power available at the cut
    torque: tuple[tuple[float, float], ...] = ()  #: (rpm, N m): the spindle's torque (turning, milling)
    max_depth: float = float("inf")  #: m: the largest depth of cut (milling a_p, turning/shaping b)
    max_width: float = float("inf")  #: m: the largest radial width a_e (milling)
    feed: float = float("nan")  #: m: feed per tooth (milling), per revolution (turning), per stroke (shaping)
    workpiece_diameter: float = float("nan")  #: m: turning, for the cutting speed pi D n
    specific_energy: float = float("nan")  #: N/m^2: cutting force per unit chip area along the cutting speed


def machine_problem(machine: Machine, kind: str | None) -> tuple[str, str] | None:
    """What is wrong with ``machine`` for a process of ``kind`` (``"turning"``,
    ``"milling"``, ``"shaping"``, ``"delay"`` or None), as ``(field, the fix)``;
    None when nothing is.  The one set of rules for the ``[machine]`` table
    and for a :class:`Machine` built in Python (field names as in the file;
    the speed limits named ``max_rpm``/``min_rpm`` for a spindle)."""
    import math

    spindle = kind in ("turning", "milling")
    unit = "m/s" if kind == "shaping" else "rpm"
    vmax, vmin = ("max_rpm", "min_rpm") if spindle else ("max_speed", "min_speed")
    if not (machine.max_speed > 0 and not math.isnan(machine.max_speed)):
        return vmax, f"must be > 0 {unit} (got {machine.max_speed:g}): the highest speed the machine runs"
    if not (math.isfinite(machine.min_speed) and machine.min_speed >= 0):
        return vmin, f"must be a finite speed >= 0 {unit} (got {machine.min_speed:g})"
    if not machine.min_speed < machine.max_speed:
        return vmin, (
            f"{machine.min_speed:g} {unit} is not below {vmax} = {machine.max_speed:g} {unit}: give {vmin} < {vmax}"
        )
    for name, curve, what in (("power", machine.power, "W"), ("torque", machine.torque, "N m")):
        for i, (v, y) in enumerate(curve):
            if not (math.isfinite(v) and v >= 0):
                return name, f"point {i + 1}: the speed must be a finite number >= 0 {unit} (got {v:g})"
            if not (math.isfinite(y) and y > 0):
                return name, f"point {i + 1}: the {name} must be a finite number > 0 {what} (got {y:g})"
            if i and not v > curve[i - 1][0]:
                return name, (
                    f"the speeds must increase from point to point (point {i + 1}, {v:g} {unit}, follows"
                    f" {curve[i - 1][0]:g} {unit}): list the curve in increasing speed"
                )
    if machine.torque and not spindle:
        return (
            "torque",
            "a spindle's torque applies to turning and milling: a shaper's drive is limited by power",
        )
    for name in ("max_depth", "max_width", "feed", "workpiece_diameter", "specific_energy"):
        v = getattr(machine, name)
        unit_ = "N/m^2" if name == "specific_energy" else "m"
        absent = v == math.inf if name in ("max_depth", "max_width") else math.isnan(v)
        if not absent and not (math.isfinite(v) and v > 0):
            return name, f"must be a finite number > 0 {unit_} (got {v:g})"
    if kind is not None and kind != "milling" and math.isfinite(machine.max_width):
        return "max_width", (
            "the largest radial width a_e applies to milling; for turning and shaping the width of cut b is"
            " the depth of cut: give max_depth"
        )
    if kind is not None and kind != "turning" and not math.isnan(machine.workpiece_diameter):
        return "workpiece_diameter", "the workpiece diameter sets the cutting speed of turning only: drop it"
    if kind == "milling" and not math.isnan(machine.specific_energy):
        return (
            "specific_energy",
            "a milling cut's power comes from [process] Kt and Kte: drop specific_energy",
        )
    return None


@dataclass(frozen=True)
class ProcessDamping:
    """Process damping of a cut (``[process_damping]``, docs/process-damping.md):
    the flank of the tool pressing on the wavy surface it has just cut.

    Linear model (Altintas, Eynian & Onozuka 2008): the force on the tool
    per unit width b is ``-C_pd (b / V) (n . dw/dt) n`` along the cut's
    normal n, V the cutting speed.  Indentation model (Wu 1989; Chiou &
    Liang 1998; Budak & Tunc 2010): the force is ``K_sp`` times the volume of
    material under the flank (wear land ``wear_land``, clearance angle
    ``clearance``), whose small-vibration equivalent is
    ``C_pd = K_sp wear_land^2 / 4`` (docs/process-damping.md, Eq. 6).
    """

    coupling: str  #: id of the [[coupling]] the term acts on
    C_pd: float  #: N/m: the linear coefficient (from K_sp w^2 / 4 for the indentation model)
    K_sp: float = float("nan")  #: N/m^3: indentation coefficient (nan: the linear model given)
    wear_land: float = float("nan")  #: m: flank wear land width
    clearance: float = float("nan")  #: rad: clearance (relief) angle of the flank
    normal: float | None = None  #: rad in CE axes: the cut's normal (None: from the coupling)

    @property
    def indentation(self) -> bool:
        """The indentation model was given (K_sp, wear land, clearance angle)."""
        return not np.isnan(self.K_sp)


@dataclass(frozen=True)
class Movable:
    """The movable subsystem (the paper's X2Y2 frame): bodies that translate
    by s along ``direction``.  Their centres in the model file are at
    s = ``position`` (the default, frozen configuration)."""

    bodies: tuple[str, ...]
    direction: tuple[float, float] = (1.0, 0.0)
    position: float = 0.0
    range: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True, eq=False)
class MatrixBlock:
    """A matrix-level model: M, L, K on named coordinates (from another FE
    code).  Arrays are read-only."""

    coordinates: tuple[str, ...]
    M: np.ndarray
    L: np.ndarray
    K: np.ndarray
    given: tuple[str, ...] = ()


@dataclass(frozen=True)
class Mode:
    """One mode of a modal model (``[[mode]]``): natural frequency ``omega``
    (rad/s), damping ratio, modal stiffness k (N/m) for the shape as written,
    and the shape entries ((physical coordinate, value), ...)."""

    id: str
    omega: float
    damping_ratio: float
    stiffness: float
    shape: tuple[tuple[str, float], ...]

    @property
    def mass(self) -> float:
        """Modal mass k / w^2, kg."""
        return self.stiffness / self.omega**2


@dataclass(frozen=True, eq=False)
class FrfSource:
    """A measured FRF as a model's structure (``[frf]``): the file as named
    in the model, its resolved path, and what was read from it (what
    :func:`chatterlab.io.read_frf` returns: plain arrays of the frequencies,
    the receptance in m/N and the output/input coordinate names)."""

    file: str
    path: str
    table: Any
    units: str | None = None
    quantity: str | None = None

    @property
    def coordinates(self) -> tuple[str, ...]:
        t = self.table
        return tuple(dict.fromkeys(tuple(t.outputs) + tuple(t.inputs)))


@dataclass(frozen=True, eq=False)
class Model:
    """An immutable machine description (the seed paper's Section 2 model).

    Build one with :func:`chatterlab.load_model`.  Items are looked up by id
    with :meth:`item`; :meth:`with_parameter` returns a changed copy.
    """

    name: str
    source: str
    bodies: tuple[Body, ...] = ()
    nodes: tuple[Node, ...] = ()
    beams: tuple[Beam, ...] = ()
    springs: tuple[Spring, ...] = ()
    attachments: tuple[Attachment, ...] = ()
    supports: tuple[Support, ...] = ()
    contacts: tuple[Contact, ...] = ()
    constraints: tuple[Constraint, ...] = ()
    points: tuple[Point, ...] = ()
    couplings: tuple[Coupling, ...] = ()
    #: [[absorber]] tuned vibration absorbers (:class:`chatterlab.model.Absorber`)
    absorbers: tuple[Any, ...] = ()
    #: [[actuator]] active dampers (:class:`chatterlab.model._actuator.Actuator`)
    actuators: tuple[Any, ...] = ()
    process: Process | None = None
    movable: Movable | None = None
    matrices: MatrixBlock | None = None
    modes: tuple[Mode, ...] = ()  #: a modal model's [[mode]] tables (``matrices`` holds their matrices)
    frf: FrfSource | None = None  #: a measured FRF as the structure ([frf])
    machine: Machine | None = None  #: the machine's and tool's limits ([machine])
    process_damping: ProcessDamping | None = None  #: [process_damping] of the cut
    ssv: SpindleSpeedVariation | None = None  #: [ssv]: a spindle-speed variation program
    variant: str | None = None
    overrides: tuple[tuple[str, Any], ...] = ()
    text: str = ""  #: the model file's text (kept for result files)
    raw: str = field(default="", repr=False)  #: the parsed TOML as JSON
    #: the reader that built this model (``build_model``), used by
    #: :meth:`with_parameters` so that the items do not import the reader
    rebuild: Any = field(default=None, repr=False, compare=False)

    @property
    def is_matrix_model(self) -> bool:
        return self.matrices is not None

    def item(self, id: str) -> Any:
        """The body, node, beam, point, spring, contact or coupling named
        ``id`` (KeyError if none)."""
        for group in (
            self.bodies,
            self.nodes,
            self.beams,
            self.points,
            self.springs,
            self.contacts,
            self.couplings,
        ):
            for it in group:
                if it.id == id:
                    return it
        raise KeyError(id)

    def with_parameter(self, path: str, value: Any) -> Model:
        """A copy with one model-file field changed.

        ``path`` addresses a field as ``KIND.ID.FIELD`` for list items (e.g.
        ``"spring.leg3-foundation.c2"``, ``"beam.table.I"``) or
        ``TABLE.FIELD`` for single tables (``"movable.position"``;
        ``"process.speed"`` for shaping, ``"process.rpm"`` for turning,
        ``"process.delay"``).  The copy is validated like a model file.
        """
        return self.with_parameters({path: value})

    def with_parameters(self, values: dict[str, Any]) -> Model:
        """Like :meth:`with_parameter` for several fields at once."""
        if self.rebuild is None:
            raise TypeError("this Model was not built by chatterlab's reader: build it with load_model")
        raw = json.loads(self.raw)
        return self.rebuild(
            raw,
            source=self.source,
            text=self.text,
            variant=self.variant,
            overrides=dict(self.overrides) | dict(values),
        )

    def with_finer_mesh(self, factor: int = 2) -> Model:
        """The same model with every ``[[beam]]`` in ``factor`` times as many
        elements (h / factor): the one place a mesh is refined, through
        :meth:`with_parameters` (the ``beam.ID.elements`` paths, after the
        model's variant and overrides).  A model without beams is returned
        unchanged (see :mod:`chatterlab.model._mesh`)."""
        if isinstance(factor, bool) or not isinstance(factor, int) or factor < 1:
            raise ValueError(f"factor must be an integer >= 1, got {factor!r}")
        if not self.beams or factor == 1:
            return self
        return self.with_parameters({f"beam.{b.id}.elements": factor * b.elements for b in self.beams})

    @property
    def beam_elements(self) -> int:
        """Every ``[[beam]]``'s element count, summed (0 without beams)."""
        return sum(b.elements for b in self.beams)

    def summary(self) -> dict[str, Any]:
        """Counts of the model's items (see also :meth:`System.summary`)."""
        return {
            "name": self.name,
            "source": self.source,
            "variant": self.variant,
            "bodies": len(self.bodies),
            "massless bodies": sum(1 for b in self.bodies if b.mass == 0.0),
            "beams": len(self.beams),
            "beam elements": self.beam_elements,
            "nodes": len(self.nodes),
            "springs": len(self.springs),
            "attachments": len(self.attachments),
            "contacts": len(self.contacts),
            "couplings": len(self.couplings),
            "matrix-level": self.is_matrix_model,
        }
