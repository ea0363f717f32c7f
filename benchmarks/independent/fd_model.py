"""A distributed-parameter machine: shaft, housing, column (two faces), bed and X screw as 1-D conduction grids.

Finite volumes along each part (64 nodes, 70 with the optional headstock block); parts join through bearings,
a motor air gap, bolted joints and screw supports; every surface loses heat to the hall air, the bed also to the
floor. Heat enters at the two bearings and the motor (rotor and stator), all ∝ (n/n_max)^p with one drawn p.
The drift is the integral of α·ΔT along the structure: z (spindle axis, + towards the table) from the shaft
nose, the housing between its clamp and the front bearing, the column below the head (against the others) and
the bed under the table; x (when logged) from the semi-closed-loop X screw; planted effects add their own terms
(column bending, centrifugal growth, ...).

Integration (:func:`simulate`): on a grid of step ``h`` the linear part dT/dt = C⁻¹(−K T + f) is advanced
exactly for inputs held over the step (zero-order hold, one augmented matrix exponential per distinct K, see
:func:`_discretise`); temperature-dependent heat (planted laws) and the chiller's tank are explicit per step.
Nothing here is taken from the library: scipy provides only ``expm``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

STEEL = {"k": 45.0, "rho_c": 3.6e6, "alpha": 11.5e-6}      # W/mK, J/m³K, 1/K
CAST_IRON = {"k": 50.0, "rho_c": 3.9e6, "alpha": 10.5e-6}


@dataclass
class Segment:
    """A 1-D grid: ``n`` finite volumes of length ``dx`` (m), cross-section ``area`` (m²), material, positions
    ``x`` (m, volume centres) and the convective perimeter (m) exposed to the hall air per unit length."""

    name: str
    n: int
    dx: float
    area: float
    mat: dict
    perimeter: np.ndarray
    start: int = 0

    @property
    def x(self) -> np.ndarray:
        return (np.arange(self.n) + 0.5) * self.dx

    @property
    def idx(self) -> np.ndarray:
        return self.start + np.arange(self.n)

    def at(self, x: float) -> int:
        """Global index of the volume containing position ``x`` (m)."""
        return self.start + int(np.clip(x / self.dx, 0, self.n - 1))


class Effect:
    """Hooks through which a planted mechanism changes the machine; the base class changes nothing."""

    block = False       # the machine carries an unmeasured headstock block

    def setup(self, m: "Machine", prog) -> None:
        """Called once before integration."""

    def ambient_g(self, m: "Machine", n: float) -> np.ndarray | None:
        """Extra conductance to the hall air per node (W/K) at speed ``n`` (rpm)."""
        return None

    def jacket(self, m: "Machine") -> tuple[np.ndarray, float] | None:
        """Coolant jacket: node weights (sum 1) and effective conductance ṁc_p·ε (W/K) to the inlet."""
        return None

    def heat(self, m: "Machine", T: np.ndarray, k: int, prog) -> np.ndarray | None:
        """Extra heat per node (W) at grid step ``k`` given the node temperatures ``T`` (°C)."""
        return None

    def drift(self, m: "Machine", T: np.ndarray, prog) -> dict[str, np.ndarray]:
        """Extra drift per channel (µm) on the grid, from the temperature history ``T`` (steps, nodes)."""
        return {}


@dataclass
class Machine:
    """Geometry, joints, sources and drift weights of one drawn machine (see the module docstring)."""

    segments: dict[str, Segment]
    C: np.ndarray                       # J/K per node
    K: np.ndarray                       # W/K, conduction and joints (symmetric, no boundaries)
    g_air: np.ndarray                   # W/K per node to the hall air
    g_floor: np.ndarray                 # W/K per node to the floor
    q_top: dict[str, np.ndarray]        # heat per node at top speed (W): front/rear bearing, rotor, stator
    p: float                            # speed exponent of every base source
    drift_w: dict[str, np.ndarray]      # µm/K per node for z and x
    info: dict = field(default_factory=dict)

    @property
    def size(self) -> int:
        return len(self.C)

    def seg(self, name: str) -> Segment:
        return self.segments[name]


FINE = {"shaft": 14, "housing": 12, "column": 10, "bed": 10, "screw": 8, "block": 6}
LUMPED = {"shaft": 3, "housing": 3, "column": 2, "bed": 2, "screw": 2, "block": 1}
MERGED = {"shaft": 2, "housing": 2, "column": 1, "bed": 1, "screw": 1, "block": 1}   # bodies merged further


def build(rng: np.random.Generator, block: bool = False, lumped: bool = False, cells: dict | None = None) -> Machine:
    """Draw a vertical machining centre (sizes, joints, sources, exposure); ``block`` adds a headstock block
    joined to the housing clamp and the column front (drawn whether or not it is used, so the rest of the
    machine is the same). ``lumped``: the other model class, a lumped network of 14–15 nodes (most of them
    unmeasured, in the heat paths and in the drift) whose topology changes per seed: 1–3 extra links drawn
    from hoses, cable chain and guards, and each part's expansion weight × U(0.5, 1.5). ``cells`` overrides the
    volumes per part (a coarser model of the same drawn machine: the draws do not depend on it)."""
    cells = cells or (LUMPED if lumped else FINE)
    r_s, L_s = rng.uniform(0.03, 0.05), rng.uniform(0.45, 0.6)
    nose = rng.uniform(0.08, 0.12)
    r_o = rng.uniform(0.09, 0.13)
    h_head = rng.uniform(12.0, 25.0)        # W/m²K on the (finned) head
    H, w_col, a_face = rng.uniform(1.0, 1.4), rng.uniform(0.35, 0.6), rng.uniform(0.03, 0.05)
    h_struct = rng.uniform(4.0, 7.0)
    L_b, a_bed = rng.uniform(1.2, 1.8), rng.uniform(0.1, 0.16)
    L_sc, r_sc = rng.uniform(0.6, 1.0), rng.uniform(0.016, 0.02)
    blk = dict(area=rng.uniform(0.04, 0.08), length=rng.uniform(0.3, 0.5), h=rng.uniform(3.0, 6.0),
               g_clamp=rng.uniform(4.0, 12.0), g_col=rng.uniform(0.5, 2.0))
    segs = {
        "shaft": Segment("shaft", cells["shaft"], L_s / cells["shaft"], np.pi * r_s ** 2, STEEL,
                         np.zeros(cells["shaft"])),
        "housing": Segment("housing", cells["housing"], (L_s - nose) / cells["housing"],
                           np.pi * (r_o ** 2 - (r_s + 0.03) ** 2), CAST_IRON,
                           np.full(cells["housing"], 2 * np.pi * r_o * h_head / h_struct)),
        "column_front": Segment("column_front", cells["column"], H / cells["column"], a_face, CAST_IRON,
                                np.full(cells["column"], 0.6)),
        "column_back": Segment("column_back", cells["column"], H / cells["column"], a_face, CAST_IRON,
                               np.full(cells["column"], 0.6)),
        "bed": Segment("bed", cells["bed"], L_b / cells["bed"], a_bed, CAST_IRON, np.full(cells["bed"], 0.9)),
        "screw": Segment("screw", cells["screw"], L_sc / cells["screw"], np.pi * r_sc ** 2, STEEL,
                         np.full(cells["screw"], 2 * np.pi * r_sc * 1.5)),
    }
    shaft = segs["shaft"]
    shaft.perimeter = np.where(shaft.x < max(nose, shaft.x[0] + 1e-9), 2 * np.pi * r_s * 1.5, 0.0)  # the nose
    if block:
        segs["block"] = Segment("block", cells["block"], blk["length"] / cells["block"], blk["area"], CAST_IRON,
                                np.full(cells["block"], 0.5))
    start = 0
    for s in segs.values():
        s.start = start
        start += s.n
    n = start
    C = np.zeros(n)
    K = np.zeros((n, n))
    g_air = np.zeros(n)

    def join(i: int, j: int, g: float) -> None:
        K[i, i] += g
        K[j, j] += g
        K[i, j] -= g
        K[j, i] -= g

    for s in segs.values():
        C[s.idx] = s.mat["rho_c"] * s.area * s.dx
        g_ax = s.mat["k"] * s.area / s.dx
        for a, b in zip(s.idx[:-1], s.idx[1:]):
            join(int(a), int(b), g_ax)
        g_air[s.idx] = h_struct * s.perimeter * s.dx
    hs = segs["housing"]
    x_h = lambda x: hs.at(x - nose)   # noqa: E731 - housing volume at shaft position x
    x_fb, x_rb = nose + rng.uniform(0.01, 0.04), L_s - rng.uniform(0.03, 0.06)
    motor = (rng.uniform(0.4, 0.5) * L_s, rng.uniform(0.65, 0.8) * L_s)
    fb, rb = shaft.at(x_fb), shaft.at(x_rb)
    join(fb, x_h(x_fb), rng.uniform(3.0, 10.0))
    join(rb, x_h(x_rb), rng.uniform(2.0, 6.0))
    in_motor = (shaft.x >= motor[0]) & (shaft.x <= motor[1])
    if not in_motor.any():
        in_motor = np.abs(shaft.x - 0.5 * (motor[0] + motor[1])) == np.abs(shaft.x - 0.5 * sum(motor)).min()
    gap = rng.uniform(1.5, 4.0)
    for i in shaft.idx[in_motor]:
        join(int(i), x_h(shaft.x[i - shaft.start]), gap / in_motor.sum())
    for i in shaft.idx[(~in_motor) & (shaft.x > x_fb + shaft.dx) & (shaft.x < x_rb - shaft.dx)]:
        join(int(i), x_h(shaft.x[i - shaft.start]), 0.05)      # still air between shaft and bore
    cf, cb, bed, sc = segs["column_front"], segs["column_back"], segs["bed"], segs["screw"]
    web = 2 * CAST_IRON["k"] * rng.uniform(0.02, 0.035) * cf.dx / w_col     # two side walls per level
    for a, b in zip(cf.idx, cb.idx):
        join(int(a), int(b), web)
    y_head = rng.uniform(0.6, 0.9) * H
    j_head = cf.at(y_head)
    x_clamp = rng.uniform(0.55, 0.8) * L_s
    g_hc = rng.uniform(3.0, 10.0)
    for x in (x_clamp - 0.05, x_clamp + 0.05):
        join(x_h(x), j_head, g_hc / 2)
    col_at = bed.at(rng.uniform(0.7, 0.9) * L_b)
    join(cf.idx[0], col_at, rng.uniform(8.0, 25.0))
    join(cb.idx[0], min(col_at + 1, bed.idx[-1]), rng.uniform(8.0, 25.0))
    table = bed.idx[: bed.at(0.5 * L_b) - bed.start + 1]
    join(sc.idx[0], bed.idx[0], rng.uniform(0.5, 1.5))     # fixed end (motor side)
    join(sc.idx[-1], bed.at(L_sc), rng.uniform(0.3, 1.0))  # floating end
    g_floor = np.zeros(n)
    g_floor[bed.idx] = rng.uniform(5.0, 15.0) / bed.n
    if block:
        bk = segs["block"]
        join(x_h(x_clamp), bk.idx[0], blk["g_clamp"])
        join(bk.idx[-1], j_head, blk["g_col"])
        g_air[bk.idx] = blk["h"] * bk.perimeter * bk.dx
    p = rng.uniform(1.2, 1.8)
    q_fb, q_rb, q_m = rng.uniform(40.0, 120.0), rng.uniform(20.0, 60.0), rng.uniform(80.0, 250.0)
    rotor = rng.uniform(0.2, 0.4)
    q_top = {k: np.zeros(n) for k in ("front_bearing", "rear_bearing", "rotor", "stator")}
    q_top["front_bearing"][[fb, x_h(x_fb)]] = q_fb / 2      # friction heat into both rings
    q_top["rear_bearing"][[rb, x_h(x_rb)]] = q_rb / 2
    q_top["rotor"][shaft.idx[in_motor]] = q_m * rotor / in_motor.sum()
    stator = np.unique([x_h(x) for x in shaft.x[in_motor]])
    q_top["stator"][stator] = q_m * (1 - rotor) / len(stator)
    w_z, w_x = np.zeros(n), np.zeros(n)
    nose_idx = shaft.idx[shaft.x < max(x_fb, shaft.x[0] + 1e-9)]
    w_z[nose_idx] = STEEL["alpha"] * x_fb / len(nose_idx) * 1e6                 # nose grows towards the table
    between = hs.idx[(hs.x + nose >= x_fb) & (hs.x + nose <= x_clamp)]
    if len(between) == 0:
        between = np.array([x_h(0.5 * (x_fb + x_clamp))])
    w_z[between] = CAST_IRON["alpha"] * (x_clamp - x_fb) / len(between) * 1e6  # housing below the clamp
    for face in (cf, cb):
        w_z[face.idx[: j_head - cf.start + 1]] -= 0.5 * CAST_IRON["alpha"] * face.dx * 1e6  # column lifts head
    w_z[table] += CAST_IRON["alpha"] * 0.3 / len(table) * 1e6                  # bed under the table rises
    s_ref = rng.uniform(0.3, 0.7) * L_sc
    on_ref = sc.idx[sc.x < max(s_ref, sc.x[0] + 1e-9)]
    w_x[on_ref] = STEEL["alpha"] * s_ref / len(on_ref) * 1e6                   # semi-closed-loop screw
    extra = {}
    if lumped:  # another topology per seed: extra heat paths, and the parts' expansion factors
        links = [("housing_bed", x_h(x_rb), bed.idx[-1]), ("stator_column", int(stator[0]), cb.idx[-1]),
                 ("screw_housing", sc.idx[-1], x_h(x_rb)), ("nose_bed", int(nose_idx[0]), int(table[0]))]
        for k in rng.choice(len(links), size=int(rng.integers(1, 4)), replace=False):
            name, i, j = links[int(k)]
            g = float(rng.uniform(0.2, 1.5))
            join(int(i), int(j), g)
            extra[name] = g
        for part in segs.values():
            f = rng.uniform(0.5, 1.5)
            w_z[part.idx] *= f
            w_x[part.idx] *= f
    info = dict(front_bearing=fb, rear_bearing=rb, housing_fb=x_h(x_fb), housing_rb=x_h(x_rb),
                motor_housing=int(stator[len(stator) // 2]), rotor=shaft.idx[in_motor], stator=stator,
                nose=nose_idx, extra_links=extra, j_head=j_head, y_head=y_head, w_col=w_col, table=table,
                col_at=col_at, clamp=x_h(x_clamp), r_s=r_s, jacket=stator, H=H)
    return Machine(segs, C, K, g_air, g_floor, q_top, p, {"z": w_z, "x": w_x}, info)


def _discretise(m: Machine, g_air: np.ndarray, extra_K: np.ndarray | None, h: float):
    """(Φ, Γ) with T(t+h) = Φ T(t) + Γ f for dT/dt = C⁻¹(−K_tot T + f), f held over the step: the blocks of
    expm([[A, C⁻¹], [0, 0]]·h) (exact for a held input)."""
    n = m.size
    K = m.K + np.diag(g_air + m.g_floor)
    if extra_K is not None:
        K = K + extra_K
    A = -K / m.C[:, None]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = A
    M[:n, n:] = np.diag(1.0 / m.C)
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


def steady_state(m: Machine, q: np.ndarray, air: float, floor: float) -> np.ndarray:
    """Node temperatures (°C) at rest with heat ``q`` (W), hall air ``air`` and floor ``floor`` (°C)."""
    K = m.K + np.diag(m.g_air + m.g_floor)
    return np.linalg.solve(K, q + m.g_air * air + m.g_floor * floor)


def base_heat(m: Machine, n: float) -> np.ndarray:
    """Heat per node (W) of bearings and motor at speed ``n`` (rpm): ∝ (n/n_max)^p."""
    s = (max(n, 0.0) / m.info["n_max"]) ** m.p
    return s * (m.q_top["front_bearing"] + m.q_top["rear_bearing"] + m.q_top["rotor"] + m.q_top["stator"])


@dataclass
class Result:
    T: np.ndarray                   # (steps, nodes) °C
    coolant_in: np.ndarray          # (steps,) °C
    drift: dict[str, np.ndarray]    # channel -> µm on the grid (relative to the start)


def simulate(m: Machine, prog, air: np.ndarray, floor: float, chiller, effect: Effect) -> Result:
    """Integrate the machine over the programme; ``air`` (°C) on the grid, ``chiller`` None when the
    machine has no coolant circuit. The machine starts in equilibrium with the first air temperature."""
    m.info["n_max"] = prog.n_max
    effect.setup(m, prog)
    jac = effect.jacket(m) if chiller is not None else None
    extra_K, g_jac, w_jac = None, 0.0, None
    if jac is not None:
        w_jac, g_jac = jac
        extra_K = g_jac * np.outer(w_jac, w_jac)
    cache: dict[float, tuple] = {}
    steps = len(prog.t)
    T = np.zeros((steps, m.size))
    cin = np.zeros(steps)
    x = steady_state(m, np.zeros(m.size), float(air[0]), floor)
    if jac is not None:  # start at rest with the jacket at the inlet temperature
        K = m.K + np.diag(m.g_air + m.g_floor) + extra_K
        x = np.linalg.solve(K, m.g_air * air[0] + m.g_floor * floor + g_jac * w_jac * chiller.inlet())
    for k in range(steps):
        n = float(prog.speed[k])
        key = round(n, 3)
        if key not in cache:
            extra_g = effect.ambient_g(m, n)
            g_air = m.g_air + (extra_g if extra_g is not None else 0.0)
            cache[key] = (*_discretise(m, g_air, extra_K, prog.h), g_air)
        Phi, Gam, g_air = cache[key]
        q = base_heat(m, n)
        dq = effect.heat(m, x, k, prog)
        if dq is not None:
            q = q + dq
        f = q + g_air * air[k] + m.g_floor * floor
        t_in = chiller.inlet() if chiller is not None else float("nan")
        if jac is not None:
            f = f + g_jac * w_jac * t_in
        T[k] = x
        cin[k] = t_in
        x = Phi @ x + Gam @ f
        if chiller is not None:
            returned = g_jac * (float(w_jac @ x) - t_in) if jac is not None else 0.0
            chiller.step(returned, float(air[k]), prog.h)
    d = T - T[0]
    drift = {c: d @ w for c, w in m.drift_w.items()}
    for c, v in effect.drift(m, T, prog).items():
        drift[c] = drift[c] + v
    return Result(T, cin, drift)
