"""Two constrained-mechanics problems of the Bari test set (Test Set for IVP Solvers, F. Mazzia,
C. Magherini et al., University of Bari), as lagcodegen ``ConstrainedSystem`` objects and as
hand transcriptions for the other contenders of benchmarks/bari.py.

* ``andrews``: Andrews' squeezing mechanism (Hairer & Wanner, Solving ODEs II, sec. VII.7;
  test set problem "andrews"): 7 rigid bodies in the plane, coordinates the 7 angles
  q = (beta, Theta, gamma, Phi, delta, Omega, epsilon), 6 holonomic constraints (three closed
  loops), driving torque mom on the crank, one spring c0 from point D of body 3 to the fixed
  point C; index 3, t in [0, 0.03].
* ``caraxis``: the car axis problem (test set problem "caraxis"; Rentrop, Roche & Steinebach
  1989): two point masses (xl, yl), (xr, yr) of mass M eps^2 / 2 joined by a rigid axis of
  length L, springs to the ground and to the wheel (xb(t), yb(t)) on a bumpy road, gravity;
  2 holonomic constraints, the first one time dependent; index 3, t in [0, 3], eps = 1e-2.

Both are written in lagcodegen's sign convention (eq. 4.5 of the notes):

    M(q) q'' = f(q, q', t) + G(q, t)^T lambda,    g(q, t) = 0,    G = dg/dq,

and the acceleration-level constraint reads G q'' + gdd(q, q', t) = 0 with gdd = d^2 g/dt^2 at
q'' = 0 (the "second derivative terms": G_q(q', q') + 2 G_t q' + g_tt). The test set writes
Andrews' mechanism as M q'' = f - G^T lambda, so its multipliers are minus lagcodegen's; it
writes the car axis with + G^T lambda, as lagcodegen does.

Sources of every number below (parameters, initial values, reference solutions): the test
set's Fortran problem files andrews.f (revision "andrews.F,v 1.2 2006/10/02") and caraxis.f
(revision "caraxis.F,v 1.2 2006/10/02"), as redistributed in the R package deTestSet
(src/Ex_andrews.f, src/Ex_car.f, R/ex_andrews.R, R/ex_caraxis.R, R/ex_reference.R), and the
test set's problem descriptions (andrews.pdf, caraxis.pdf), which take Andrews' mechanism
from Hairer & Wanner II, sec. VII.7.

How well the references are known (measured for issue 16: scipy DOP853 at rtol 1e-13 and
Radau at rtol 1e-12 on the numpy index-1 transcription below, which agree with each other to
6e-13 in the positions and 4e-12 in the multipliers, and lagcodegen's GGL at rtol 1e-12):

* Andrews: the published reference (PSIDE at rtol = atol = 1e-14 in Cray double precision)
  is less accurate than its 16 digits: it differs from both independent integrations by
  2.7e-10 (relative, gamma) in the positions, 5e-8 in the velocities and 1.3e-6 in the
  multipliers, the same amounts for both, and it misses its own hidden constraints (G v =
  7e-10 where the integrations give 1e-13; G q'' + gdd = 1e-3). Errors below ~1e-9 must be
  measured against a computed reference (benchmarks/bari.py does by default).
* car axis: the description's 21-digit values agree with the integrations to 4e-13 in the
  positions and 2e-12 in the multipliers; the Fortran file's carsoln is as good in the
  positions but off by 7e-8 (relative) in the multipliers.

Nothing here integrates anything; benchmarks/bari.py and tests/test_bari_problems.py do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

# --------------------------------------------------------------------------- Andrews
#: Parameters of Andrews' squeezing mechanism (andrews.f, subroutine andpar / deTestSet
#: ex_andrews.R; from Hairer & Wanner II, sec. VII.7): masses m_k, moments of inertia i_k, fixed
#: points A, B, C, geometry, spring c0 with rest length l0, driving torque mom.
ANDREWS_PARAMS = dict(
    m1=0.04325, m2=0.00365, m3=0.02373, m4=0.00706, m5=0.07050, m6=0.00706, m7=0.05498,
    xa=-0.06934, ya=-0.00227, xb=-0.03635, yb=0.03273, xc=0.014, yc=0.072, c0=4530.0,
    i1=2.194e-6, i2=4.410e-7, i3=5.255e-6, i4=5.667e-7, i5=1.169e-5, i6=5.667e-7, i7=1.912e-5,
    d=28e-3, da=115e-4, e=2e-2, ea=1421e-5, rr=7e-3, ra=92e-5, l0=7785e-5,
    ss=35e-3, sa=1874e-5, sb=1043e-5, sc=18e-3, sd=2e-2, ta=2308e-5, tb=916e-5,
    u=4e-2, ua=1228e-5, ub=449e-5, zf=2e-2, zt=4e-2, fa=1421e-5, mom=33e-3,
)
ANDREWS_COORDS = ("beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon")
ANDREWS_T = (0.0, 0.03)
#: Consistent initial values (andrews.f / the description, sec. "initial values"): the angles;
#: all velocities are zero.
ANDREWS_Q0 = np.array([-0.0617138900142764496358948458001, 0.0, 0.455279819163070380255912382449,
                       0.222668390165885884674473185609, 0.487364979543842550225598953530,
                       -0.222668390165885884674473185609, 1.23054744454982119249735015568])
ANDREWS_V0 = np.zeros(7)
#: Consistent initial accelerations and multipliers (description; multipliers in the test set's
#: sign, M q'' = f - G^T lambda): used to check the transcriptions.
ANDREWS_A0 = np.array([14222.4439199541138705911625887, -10666.8329399655854029433719415, 0, 0, 0, 0, 0])
ANDREWS_LAMBDA0_TESTSET = np.array([98.5668703962410896057654982170, -6.12268834425566265503114393122,
                                    0, 0, 0, 0])
#: Reference solution at t = 0.03 (andrews.f, subroutine andsoln: "computed at Cray C90, using
#: Cray double precision: Solving Andrews' squeezing mechanism using PSIDE, rtol = atol = 1e-14,
#: 1112 steps"): y(1..7) the angles, y(8..14) their velocities, y(15..21) the accelerations,
#: y(22..27) the multipliers in the test set's sign.
_ANDSOLN = [
    0.1581077119629904e+2, -0.1575637105984298e+2, 0.4082224013073101e-1, -0.5347301163226948e+0,
    0.5244099658805304e+0, 0.5347301163226948e+0, 0.1048080741042263e+1,
    0.1139920302151208e+4, -0.1424379294994111e+4, 0.1103291221937134e+2, 0.1929337464421385e+2,
    0.5735699284790808e+0, -0.1929337464421385e+2, 0.3231791658026955e+0,
    -0.2463176316945196e+5, 0.5185037701610329e+5, 0.3241025686413781e+6, 0.5667493645176213e+6,
    0.1674362929479361e+5, -0.5667493645176222e+6, 0.9826520791458422e+4,
    0.1991753333731910e+3, -0.2975531228015052e+2, 0.2306654119098399e+2, 0.3145271365475927e+2,
    0.2264249232082739e+2, 0.1161740700019673e+2,
]


def andrews_terms(q, v, t, P, mod):
    """(M, f, g, G, gdd) of Andrews' squeezer at (q, v) as nested lists of scalars (andrews.f,
    in lagcodegen's sign: M q'' = f + G^T lambda with lambda = -lambda_testset).

    ``P``: the parameters (:data:`ANDREWS_PARAMS`); ``mod``: where sin, cos, sqrt come from
    (``math`` for floats, ``casadi`` for symbols). t is unused (autonomous)."""
    sin, cos, sqrt = mod.sin, mod.cos, mod.sqrt
    be, th, ga, ph, de, om, ep = q
    bep, thp, gap, php, dep, omp, epp = v
    m1, m2, m3, m4, m5, m6, m7 = (P[k] for k in ("m1", "m2", "m3", "m4", "m5", "m6", "m7"))
    i1, i2, i3, i4, i5, i6, i7 = (P[k] for k in ("i1", "i2", "i3", "i4", "i5", "i6", "i7"))
    xa, ya, xb, yb, xc, yc = (P[k] for k in ("xa", "ya", "xb", "yb", "xc", "yc"))
    d, da, e, ea, rr, ra, l0 = (P[k] for k in ("d", "da", "e", "ea", "rr", "ra", "l0"))
    ss, sa, sb, sc, sd, ta, tb = (P[k] for k in ("ss", "sa", "sb", "sc", "sd", "ta", "tb"))
    u, ua, ub, zf, zt, fa, mom, c0 = (P[k] for k in ("u", "ua", "ub", "zf", "zt", "fa", "mom", "c0"))
    sibe, sith, siga, siph, side, siom, siep = sin(be), sin(th), sin(ga), sin(ph), sin(de), sin(om), sin(ep)
    cobe, coth, coga, coph, code, coom, coep = cos(be), cos(th), cos(ga), cos(ph), cos(de), cos(om), cos(ep)
    sibeth, cobeth = sin(be + th), cos(be + th)
    siphde, cophde = sin(ph + de), cos(ph + de)
    siomep, coomep = sin(om + ep), cos(om + ep)

    Z = 0.0
    M = [[Z] * 7 for _ in range(7)]
    M[0][0] = m1 * ra**2 + m2 * (rr**2 - 2 * da * rr * coth + da**2) + i1 + i2
    M[1][0] = M[0][1] = m2 * (da**2 - da * rr * coth) + i2
    M[1][1] = m2 * da**2 + i2
    M[2][2] = m3 * (sa**2 + sb**2) + i3
    M[3][3] = m4 * (e - ea)**2 + i4
    M[4][3] = M[3][4] = m4 * ((e - ea)**2 + zt * (e - ea) * siph) + i4
    M[4][4] = m4 * (zt**2 + 2 * zt * (e - ea) * siph + (e - ea)**2) + m5 * (ta**2 + tb**2) + i4 + i5
    M[5][5] = m6 * (zf - fa)**2 + i6
    M[6][5] = M[5][6] = m6 * ((zf - fa)**2 - u * (zf - fa) * siom) + i6
    M[6][6] = m6 * ((zf - fa)**2 - 2 * u * (zf - fa) * siom + u**2) + m7 * (ua**2 + ub**2) + i6 + i7

    xd = sd * coga + sc * siga + xb
    yd = sd * siga - sc * coga + yb
    lang = sqrt((xd - xc)**2 + (yd - yc)**2)
    force = -c0 * (lang - l0) / lang
    fx, fy = force * (xd - xc), force * (yd - yc)
    f = [mom - m2 * da * rr * thp * (thp + 2 * bep) * sith,
         m2 * da * rr * bep**2 * sith,
         fx * (sc * coga - sd * siga) + fy * (sd * coga + sc * siga),
         m4 * zt * (e - ea) * dep**2 * coph,
         -m4 * zt * (e - ea) * php * (php + 2 * dep) * coph,
         -m6 * u * (zf - fa) * epp**2 * coom,
         m6 * u * (zf - fa) * omp * (omp + 2 * epp) * coom]

    g = [rr * cobe - d * cobeth - ss * siga - xb,
         rr * sibe - d * sibeth + ss * coga - yb,
         rr * cobe - d * cobeth - e * siphde - zt * code - xa,
         rr * sibe - d * sibeth + e * cophde - zt * side - ya,
         rr * cobe - d * cobeth - zf * coomep - u * siep - xa,
         rr * sibe - d * sibeth - zf * siomep + u * coep - ya]

    G = [[Z] * 7 for _ in range(6)]
    G[0][0], G[0][1], G[0][2] = -rr * sibe + d * sibeth, d * sibeth, -ss * coga
    G[1][0], G[1][1], G[1][2] = rr * cobe - d * cobeth, -d * cobeth, -ss * siga
    G[2][0], G[2][1], G[2][3], G[2][4] = -rr * sibe + d * sibeth, d * sibeth, -e * cophde, -e * cophde + zt * side
    G[3][0], G[3][1], G[3][3], G[3][4] = rr * cobe - d * cobeth, -d * cobeth, -e * siphde, -e * siphde - zt * code
    G[4][0], G[4][1], G[4][5], G[4][6] = -rr * sibe + d * sibeth, d * sibeth, zf * siomep, zf * siomep - u * coep
    G[5][0], G[5][1], G[5][5], G[5][6] = rr * cobe - d * cobeth, -d * cobeth, -zf * coomep, -zf * coomep - u * siep

    # d^2 g / dt^2 at q'' = 0 (every g_j is a sum of terms c * cos/sin(angle sum))
    w_bt, w_pd, w_oe = bep + thp, php + dep, omp + epp
    crank_x = -rr * cobe * bep**2 + d * cobeth * w_bt**2
    crank_y = -rr * sibe * bep**2 + d * sibeth * w_bt**2
    gdd = [crank_x + ss * siga * gap**2,
           crank_y - ss * coga * gap**2,
           crank_x + e * siphde * w_pd**2 + zt * code * dep**2,
           crank_y - e * cophde * w_pd**2 + zt * side * dep**2,
           crank_x + zf * coomep * w_oe**2 + u * siep * epp**2,
           crank_y + zf * siomep * w_oe**2 - u * coep * epp**2]
    return M, f, g, G, gdd


def andrews_system(name: str = "andrews"):
    """Andrews' squeezer as a lagcodegen ConstrainedSystem, written from its seven bodies.

    Each body is a planar rigid body (mass, moment of inertia about its centre of mass,
    position of that centre, absolute angle); T = sum m/2 |x_G'|^2 + I/2 angle'^2 then
    reproduces the published mass matrix (andrews.f, m(i,j)) term by term:

    * 1 crank O-K, angle beta, centre at distance ra from O;
    * 2 rod K-F, angle beta + Theta, centre at distance da from K (K at rr from O);
    * 3 triangle at B, angle gamma, centre at distance sqrt(sa^2 + sb^2) from B; the spring acts
      at its point D = B + sd (cos g, sin g) + sc (sin g, -cos g);
    * 5 triangle at A, angle delta, centre at (ta, tb) in its frame;
    * 4 rod from body 5's point A + zt (cos delta, sin delta), angle Phi + delta, centre at
      distance e - ea along (sin, -cos)(Phi + delta);
    * 7 triangle at A, angle epsilon, centre at (ua, ub) in its frame;
    * 6 rod from body 7's point A + u (sin eps, -cos eps), angle Omega + epsilon, centre at
      distance zf - fa along (cos, sin)(Omega + epsilon).

    (The published mass matrix fixes only the distances of the centres from the joints and the
    relative orientations that enter the cross terms, which is all the kinetic energy depends
    on; where a centre lies in its body's frame is chosen to match those.) Forces: the driving
    torque mom on beta and the spring c0 (rest length l0) between D and the fixed point C,
    V = c0/2 (|D - C| - l0)^2, whose generalized force is the published f_3. The six
    constraints g = 0 (three closed loops) are the published ones.
    """
    import sympy as sp

    import lagcodegen as lcg
    from lagcodegen.theory.constraints import ConstrainedSystem

    m = lcg.Model(name)
    be, th, ga, ph, de, om, ep = m.coordinates(" ".join(ANDREWS_COORDS))
    P = dict(zip(ANDREWS_PARAMS, m.parameters(**ANDREWS_PARAMS)))
    cos, sin = sp.cos, sp.sin
    A = (P["xa"], P["ya"])
    B = (P["xb"], P["yb"])

    def add(p, *terms):
        return tuple(p[i] + sum(term[i] for term in terms) for i in range(2))

    def along(c, angle):  # c (cos, sin)(angle)
        return (c * cos(angle), c * sin(angle))

    def across(c, angle):  # c (sin, -cos)(angle)
        return (c * sin(angle), -c * cos(angle))

    K = along(P["rr"], be)
    m.planar_body("crank", P["m1"], P["i1"], along(P["ra"], be), be)
    m.planar_body("rod_KF", P["m2"], P["i2"], add(K, along(-P["da"], be + th)), be + th)
    m.planar_body("body3", P["m3"], P["i3"], add(B, along(P["sa"], ga), across(P["sb"], ga)), ga)
    m.planar_body("body5", P["m5"], P["i5"], add(A, along(P["ta"], de), along(P["tb"], de + sp.pi / 2)), de)
    m.planar_body("rod4", P["m4"], P["i4"], add(A, along(P["zt"], de), across(P["e"] - P["ea"], ph + de)), ph + de)
    m.planar_body("body7", P["m7"], P["i7"], add(A, along(P["ua"], ep), along(P["ub"], ep + sp.pi / 2)), ep)
    m.planar_body("rod6", P["m6"], P["i6"], add(A, across(P["u"], ep), along(P["zf"] - P["fa"], om + ep)),
                  om + ep)
    D = m.point("D", add(B, along(P["sd"], ga), across(P["sc"], ga)))
    m.spring(D, (P["xc"], P["yc"]), P["c0"], P["l0"], label="spring D-C")
    m.generalized_force(be, P["mom"], label="driving torque")

    rr, d, ss, e, zt, zf, u = (P[k] for k in ("rr", "d", "ss", "e", "zt", "zf", "u"))
    F = (rr * cos(be) - d * cos(be + th), rr * sin(be) - d * sin(be + th))  # the joint F of rod K-F
    loops = [F[0] - ss * sin(ga) - B[0],
             F[1] + ss * cos(ga) - B[1],
             F[0] - e * sin(ph + de) - zt * cos(de) - A[0],
             F[1] + e * cos(ph + de) - zt * sin(de) - A[1],
             F[0] - zf * cos(om + ep) - u * sin(ep) - A[0],
             F[1] - zf * sin(om + ep) + u * cos(ep) - A[1]]
    return ConstrainedSystem(m, holonomic=loops)


# --------------------------------------------------------------------------- car axis
#: Parameters of the car axis problem (caraxis.f, subroutine carpar / deTestSet ex_caraxis.R).
CARAXIS_PARAMS = dict(eps=1e-2, M=10.0, L=1.0, L0=0.5, r=0.1, w=10.0, g=1.0)
CARAXIS_COORDS = ("xl", "yl", "xr", "yr")
CARAXIS_T = (0.0, 3.0)
#: Consistent initial values (description): xl = 0, yl = L0, xr = L, yr = L0,
#: xl' = -L0/L, yl' = 0, xr' = -L0/L, yr' = 0 (and lambda = 0).
CARAXIS_Q0 = np.array([0.0, 0.5, 1.0, 0.5])
CARAXIS_V0 = np.array([-0.5, 0.0, -0.5, 0.0])
#: Reference solution at t = 3 from the test set's description (caraxis.pdf, 21 digits; also
#: deTestSet R/ex_reference.R): positions, velocities, then lambda_1, lambda_2 (same sign
#: convention as lagcodegen).
_CARAXIS_REF_DESCRIPTION = [
    0.493455784275402809122e-1, 0.496989460230171153861, 0.104174252488542151681e1, 0.373911027265361256927,
    -0.770583684040972357970e-1, 0.744686658723778553466e-2, 0.175568157537232222276e-1,
    0.770341043779251976443, -0.473688659084893324729e-2, -0.110468033125734368808e-2,
]
#: The same from the Fortran file (caraxis.f, subroutine carsoln), 16 digits: differs from the
#: description's by up to 2e-13 (positions) and 3e-7 relative (multipliers).
_CARAXIS_REF_FORTRAN = [
    0.4934557842755629e-1, 0.4969894602303324e+0, 0.1041742524885400e+1, 0.3739110272652214e+0,
    -0.7705836840321485e-1, 0.7446866596327776e-2, 0.1755681574942899e-1, 0.7703410437794031e+0,
    -0.4736886750784630e-2, -0.1104680411345730e-2,
]


def caraxis_terms(q, v, t, P, mod):
    """(M, f, g, G, gdd) of the car axis at (q, v, t) as nested lists (caraxis.f, carfunc:
    k q'' = f + G^T lambda with k = M eps^2 / 2; the multipliers are the test set's)."""
    sin, cos, sqrt = mod.sin, mod.cos, mod.sqrt
    xl, yl, xr, yr = q
    vxl, vyl, vxr, vyr = v
    eps, Mass, L, L0, r, w, grav = (P[k] for k in ("eps", "M", "L", "L0", "r", "w", "g"))
    k = Mass * eps * eps / 2
    yb = r * sin(w * t)
    yb1 = r * w * cos(w * t)
    yb2 = -r * w * w * sin(w * t)
    xb = sqrt(L * L - yb * yb)
    xb1 = -yb * yb1 / xb
    xb2 = -(yb1 * yb1 + yb * yb2) / xb - (yb * yb1) ** 2 / xb**3
    Ll = sqrt(xl**2 + yl**2)
    Lr = sqrt((xr - xb)**2 + (yr - yb)**2)
    Z = 0.0
    M = [[k if i == j else Z for j in range(4)] for i in range(4)]
    f = [(L0 - Ll) * xl / Ll, (L0 - Ll) * yl / Ll - k * grav,
         (L0 - Lr) * (xr - xb) / Lr, (L0 - Lr) * (yr - yb) / Lr - k * grav]
    g = [xb * xl + yb * yl, (xl - xr)**2 + (yl - yr)**2 - L * L]
    G = [[xb, yb, Z, Z], [2 * (xl - xr), 2 * (yl - yr), -2 * (xl - xr), -2 * (yl - yr)]]
    gdd = [xb2 * xl + 2 * xb1 * vxl + yb2 * yl + 2 * yb1 * vyl,
           2 * (vxl - vxr)**2 + 2 * (vyl - vyr)**2]
    return M, f, g, G, gdd


def caraxis_system(name: str = "caraxis"):
    """The car axis as a lagcodegen ConstrainedSystem: two particles of mass k = M eps^2 / 2 in
    gravity g, a spring (stiffness 1, rest length L0) from the origin to the left mass and one
    from the wheel (xb(t), yb(t)) = (sqrt(L^2 - yb^2), r sin(w t)) to the right mass; the
    constraints xb xl + yb yl = 0 (the left end moves perpendicular to the wheel's arm) and
    |left - right| = L (the axis)."""
    import sympy as sp

    import lagcodegen as lcg
    from lagcodegen.theory.constraints import ConstrainedSystem

    m = lcg.Model(name)
    xl, yl, xr, yr = m.coordinates(" ".join(CARAXIS_COORDS))
    eps, Mass, L, L0, r, w, g = m.parameters(**CARAXIS_PARAMS)
    k = Mass * eps**2 / 2
    yb = r * sp.sin(w * m.t)
    xb = sp.sqrt(L**2 - yb**2)
    m.particle("left", k, (xl, yl))
    m.particle("right", k, (xr, yr))
    m.gravity(g)
    m.spring("left", (0, 0), 1, L0, label="spring origin-left")
    m.spring("right", (xb, yb), 1, L0, label="spring wheel-right")
    return ConstrainedSystem(m, holonomic=[xb * xl + yb * yl, (xl - xr)**2 + (yl - yr)**2 - L**2])


# --------------------------------------------------------------------------- common
@dataclass
class Problem:
    """One problem: its data, its lagcodegen system and its numpy transcription.

    ``ref_q``, ``ref_v``, ``ref_lam``: the published state at ``t1`` (multipliers in
    lagcodegen's sign); ``terms(q, v, t, P, mod)``: the transcription (M, f, g, G, gdd)."""

    name: str
    title: str
    coords: tuple
    params: dict
    t0: float
    t1: float
    q0: np.ndarray
    v0: np.ndarray
    ref_q: np.ndarray
    ref_v: np.ndarray
    ref_lam: np.ndarray
    terms: Callable
    make_system: Callable
    source: str
    extra: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.coords)

    @property
    def nc(self) -> int:
        return len(self.ref_lam)

    def system(self, name: str | None = None):
        return self.make_system(name or self.name)

    # ------------------------------------------------------------------ numpy transcription
    def numeric(self, q, v=None, t: float = 0.0):
        """(M, f, g, G, gdd) as numpy arrays at (q, v, t)."""
        v = np.zeros(self.n) if v is None else v
        M, f, g, G, gdd = self.terms([float(x) for x in q], [float(x) for x in v], float(t), self.params, math)
        return np.array(M, float), np.array(f, float), np.array(g, float), np.array(G, float), np.array(gdd, float)

    def M(self, q, t=0.0):
        return self.numeric(q, None, t)[0]

    def f(self, q, v, t=0.0):
        return self.numeric(q, v, t)[1]

    def g(self, q, t=0.0):
        return self.numeric(q, None, t)[2]

    def G(self, q, t=0.0):
        return self.numeric(q, None, t)[3]

    def gdd(self, q, v, t=0.0):
        return self.numeric(q, v, t)[4]

    def kkt(self, q, v, t=0.0):
        """(q'', lambda) from [M -G^T; G 0] [q''; lambda] = [f; -gdd] (lagcodegen's sign)."""
        M, f, _, G, gdd = self.numeric(q, v, t)
        n, c = self.n, self.nc
        K = np.zeros((n + c, n + c))
        K[:n, :n], K[:n, n:], K[n:, :n] = M, -G.T, G
        sol = np.linalg.solve(K, np.concatenate([f, -gdd]))
        return sol[:n], sol[n:]

    def index1_rhs(self, t, y):
        """The index-1 ODE y' = (q', q'') of y = (q, q') (no stabilization): for scipy."""
        n = self.n
        acc, _ = self.kkt(y[:n], y[n:], t)
        return np.concatenate([y[n:], acc])

    def max_g(self, qs, ts) -> float:
        """max over rows and constraints of |g(q, t)| (rows of ``qs`` at times ``ts``)."""
        return max(float(np.max(np.abs(self.g(q, t)))) for q, t in zip(np.atleast_2d(qs), np.atleast_1d(ts)))

    def position_error(self, q) -> float:
        """max_i |q_i - ref_i| / |ref_i| at t1 (the work-precision error)."""
        return float(np.max(np.abs(np.asarray(q, float) - self.ref_q) / np.abs(self.ref_q)))

    def multiplier_error(self, lam) -> float:
        """max_j |lambda_j - ref_j| / |ref_j| at t1 (lagcodegen's sign)."""
        if lam is None:
            return float("nan")
        return float(np.max(np.abs(np.asarray(lam, float) - self.ref_lam) / np.abs(self.ref_lam)))


def andrews() -> Problem:
    ref = np.array(_ANDSOLN)
    return Problem(
        "andrews", "Andrews' squeezing mechanism (7 angles, 6 constraints, index 3), t in [0, 0.03]",
        ANDREWS_COORDS, dict(ANDREWS_PARAMS), *ANDREWS_T, ANDREWS_Q0.copy(), ANDREWS_V0.copy(),
        ref[:7], ref[7:14], -ref[21:27], andrews_terms, andrews_system,
        "test set andrews.f, andsoln (PSIDE, rtol = atol = 1e-14, Cray double precision)",
        extra={"ref_acc": ref[14:21], "a0": ANDREWS_A0.copy(), "lambda0": -ANDREWS_LAMBDA0_TESTSET})


def caraxis() -> Problem:
    ref = np.array(_CARAXIS_REF_DESCRIPTION)
    return Problem(
        "caraxis", "Car axis (4 coordinates, 2 constraints, index 3, eps = 1e-2), t in [0, 3]",
        CARAXIS_COORDS, dict(CARAXIS_PARAMS), *CARAXIS_T, CARAXIS_Q0.copy(), CARAXIS_V0.copy(),
        ref[:4], ref[4:8], ref[8:10], caraxis_terms, caraxis_system,
        "test set description caraxis.pdf (21 digits; = deTestSet ex_reference.R)",
        extra={"ref_fortran": np.array(_CARAXIS_REF_FORTRAN), "a0": None, "lambda0": np.zeros(2)})


# --------------------------------------------------------------------------- Cartesian pendulum
#: Not a Bari problem: the Cartesian pendulum of benchmarks/constraint_drift.py (x^2 + y^2 = l^2,
#: l = 1, g = 9.81, m = 1, released from 1 rad at rest), over t in [0, 20], as a third,
#: easy data point for choosing the default formulation. Its reference comes from the angle
#: model theta'' = -g/l sin(theta) (see :func:`pendulum_reference`).
PENDULUM_PARAMS = dict(l=1.0, g=9.81, m=1.0)
PENDULUM_THETA0 = 1.0
PENDULUM_T = (0.0, 20.0)


def pendulum_terms(q, v, t, P, mod):
    """(M, f, g, G, gdd) of the Cartesian pendulum (M q'' = f + G^T lambda)."""
    x, y = q
    vx, vy = v
    m, grav, l = P["m"], P["g"], P["l"]
    Z = 0.0
    return ([[m, Z], [Z, m]], [Z, -m * grav], [x * x + y * y - l * l], [[2 * x, 2 * y]],
            [2 * (vx * vx + vy * vy)])


def pendulum_system(name: str = "bari_pendulum"):
    import lagcodegen as lcg
    from lagcodegen.theory.constraints import ConstrainedSystem

    m = lcg.Model(name)
    x, y = m.coordinates("x y")
    l, g, mass = m.parameters(**PENDULUM_PARAMS)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=[x**2 + y**2 - l**2])


def pendulum_reference(rtol: float = 1e-13):
    """(q, v, lambda) at t1 from the angle model (scipy DOP853, atol = rtol/100): the bob at
    (l sin th, -l cos th) and, with A = (2x, 2y), lambda = -m (g cos th + l th'^2) / (2 l)."""
    from scipy.integrate import solve_ivp
    P = PENDULUM_PARAMS
    sol = solve_ivp(lambda t, y: [y[1], -P["g"] / P["l"] * math.sin(y[0])], PENDULUM_T, [PENDULUM_THETA0, 0.0],
                    method="DOP853", rtol=rtol, atol=rtol / 100)
    th, om = sol.y[:, -1]
    l = P["l"]
    q = np.array([l * math.sin(th), -l * math.cos(th)])
    v = np.array([l * math.cos(th) * om, l * math.sin(th) * om])
    lam = np.array([-P["m"] * (P["g"] * math.cos(th) + l * om * om) / (2 * l)])
    return q, v, lam


def pendulum() -> Problem:
    q, v, lam = pendulum_reference()
    th = PENDULUM_THETA0
    return Problem(
        "pendulum", "Cartesian pendulum x^2 + y^2 = 1 from 1 rad (not a Bari problem), t in [0, 20]",
        ("x", "y"), dict(PENDULUM_PARAMS), *PENDULUM_T, np.array([math.sin(th), -math.cos(th)]), np.zeros(2),
        q, v, lam, pendulum_terms, pendulum_system,
        "angle model theta'' = -g sin(theta), scipy DOP853 at rtol 1e-13", extra={"a0": None, "lambda0": None})


PROBLEMS = {"andrews": andrews, "caraxis": caraxis, "pendulum": pendulum}
