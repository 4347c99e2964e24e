"""Built-in parametric garment templates (the project's own), defined from body measurements
and placed around a body given by its BodyLandmarks (metres; Y up, body faces +Z, +X is the
body's left).

Tops (t-shirt, long-sleeve, short-sleeve dress) are a front and a back panel wrapped around a
vertical cylinder about the torso a few cm outside the chest, and one sleeve panel per arm
wrapped into a tube around the arm axis (underarm seam closed, cap sewn to the front and back
armholes; long sleeves bend at the elbow). The skirt is a front and a back panel laid on the
torso's cross-sections. The trousers are a front and a back panel per leg, each leg laid as a
tube around its leg axis, the seat on the torso's cross-sections. Every sewn pair of edges has
the same length in the pattern (the sleeve cap height and the back crotch point are solved for
it), so the seam-length regularizer is zero at the template. All lengths below are in metres."""
from __future__ import annotations

from dataclasses import dataclass, asdict, replace

import numpy as np

from ..landmarks import BodyLandmarks
from .garment import Garment
from .spec import PanelSpec, PatternSpec, Placement, SeamSpec, build_garment


def default_landmarks() -> BodyLandmarks:
    """An average adult (1.75 m) in an A-pose (arms 40° from the body), origin between the feet."""
    s40, c40 = np.sin(np.radians(40)), np.cos(np.radians(40))
    sh = np.array([0.19, 1.45, 0.0])
    el = sh + 0.29 * np.array([s40, -c40, 0.0])
    wr = el + 0.26 * np.array([s40, -c40, 0.0])
    mirror = np.array([-1.0, 1.0, 1.0])
    return BodyLandmarks(
        height=1.75, chest_girth=0.96, waist_girth=0.82, hip_girth=1.0,
        neck_base=np.array([0.0, 1.50, 0.0]),
        shoulder_left=sh, shoulder_right=sh * mirror, elbow_left=el, elbow_right=el * mirror,
        wrist_left=wr, wrist_right=wr * mirror,
        chest_center=np.array([0.0, 1.30, 0.0]), waist_center=np.array([0.0, 1.08, 0.0]),
        hip_center=np.array([0.0, 0.95, 0.0]),
        knee_left=np.array([0.10, 0.52, 0.0]), knee_right=np.array([-0.10, 0.52, 0.0]),
        ankle_left=np.array([0.10, 0.08, 0.0]), ankle_right=np.array([-0.10, 0.08, 0.0]))


def torso_radius(lm: BodyLandmarks, girth: float) -> float:
    """Radius (m) of a vertical cylinder that contains a torso cross-section of this girth:
    the torso is wider than deep, its half-width is about 1.2 × girth / 2π."""
    return 1.2 * girth / (2 * np.pi)


@dataclass
class TopMeasurements:
    """Garment measurements of a top (m). ease: added to the chest girth."""
    length: float = 0.70             # neck point to hem
    ease: float = 0.10
    hem_flare: float = 0.0           # added to the hem's half circumference (dresses)
    neck_width: float = 0.17
    front_neck_depth: float = 0.08
    back_neck_depth: float = 0.025
    shoulder_slope: float = 0.04
    armhole_depth: float = 0.22      # shoulder point to armpit, vertical
    sleeve_length: float = 0.22      # underarm to cuff
    bicep_width: float = 0.36        # sleeve width at the armpit
    cuff_width: float = 0.32
    gap: float = 0.03                # distance of the placed sheet outside the body
    fold_radius: float | None = None  # bend of the panels over the shoulders (placement only);
    # None: 0.17 m, grown until the fold's top clears the neck base (see _top_spec)


@dataclass
class SkirtMeasurements:
    length: float = 0.55
    waist_ease: float = 0.04
    hem_width: float = 1.30          # hem circumference
    gap: float = 0.03


def _top_spec(name: str, lm: BodyLandmarks, m: TopMeasurements) -> PatternSpec:
    W = (lm.chest_girth + m.ease) / 2                 # front/back width at the chest
    Wh = W + m.hem_flare                              # at the hem
    S = float(np.linalg.norm(lm.shoulder_left - lm.shoulder_right)) + 0.02
    L, N = m.length, m.neck_width
    Ls = L - m.shoulder_slope - m.armhole_depth       # side seam length (vertical extent)

    def body(neck_depth):
        V = np.array([[-Wh / 2, 0], [Wh / 2, 0], [W / 2, Ls], [S / 2, L - m.shoulder_slope],
                      [N / 2, L], [-N / 2, L], [-S / 2, L - m.shoulder_slope], [-W / 2, Ls]])
        curves = {
            2: [[S / 2 - 0.01, Ls + 0.35 * m.armhole_depth]],      # armholes, scooped inward
            6: [[-S / 2 + 0.01, Ls + 0.35 * m.armhole_depth]],
            4: [[0.0, L - 2 * neck_depth]],                         # neckline
        }
        return V, curves

    Rt = max(torso_radius(lm, lm.chest_girth), Wh / np.pi) + m.gap
    axis = lm.chest_center
    hem_y = lm.neck_base[1] - L + 0.06
    Vf, cf = body(m.front_neck_depth)
    Vb, cb = body(m.back_neck_depth)
    # above the armpits the panels fold over the shoulders towards each other
    # (the fold's top, fold_at + radius above the hem, must clear the neck base: on a body
    # whose neck sits high above the armpits a lower fold cut through the trapezius)
    # Measured on the default body: the t-shirt needs the grown fold (else 7-13 mm penetration
    # at the shoulder blade); the long-sleeve shirt and the dress drape clean with 0.17 m and
    # not with the grown fold (the dress slid off, the long sleeve cut the upper back).
    fold_r = m.fold_radius if m.fold_radius is not None else \
        max(0.17, lm.neck_base[1] + m.gap - (hem_y + Ls))
    fold = dict(radius=Rt, fold_at=Ls, fold_radius=fold_r)
    front = PanelSpec("front", Vf, Placement([axis[0], hem_y, axis[2] + Rt], [1, 0, 0], [0, 1, 0], **fold),
                      curves=cf, boundary={0: "hem", 4: "neckline"})
    back = PanelSpec("back", Vb, Placement([axis[0], hem_y, axis[2] - Rt], [-1, 0, 0], [0, 1, 0], **fold),
                     curves=cb, boundary={0: "hem", 4: "neckline"})
    armhole = front.edge_length(2)
    panels = [front, back]
    seams = [SeamSpec("front", 1, "back", 7), SeamSpec("front", 7, "back", 1),
             SeamSpec("front", 3, "back", 5), SeamSpec("front", 5, "back", 3)]
    if m.sleeve_length > 0:
        Wb, Wc, Lu = m.bicep_width, m.cuff_width, m.sleeve_length
        cap_h = _solve_cap_height(Wb, armhole)
        Vs = np.array([[-Wc / 2, 0], [Wc / 2, 0], [Wb / 2, Lu], [0, Lu + cap_h], [-Wb / 2, Lu]])
        cs = {2: [[Wb / 4 + 0.02, Lu + 0.75 * cap_h]], 3: [[-Wb / 4 - 0.02, Lu + 0.75 * cap_h]]}
        Rs = Wb / (2 * np.pi)
        for side, sh, far in (("left", lm.shoulder_left, lm.elbow_left if Lu < 0.35 else lm.wrist_left),
                              ("right", lm.shoulder_right, lm.elbow_right if Lu < 0.35 else lm.wrist_right)):
            ey = sh - far
            ey /= np.linalg.norm(ey)
            up = np.array([0.0, 1.0, 0.0]) - ey[1] * ey
            up /= np.linalg.norm(up)
            ex = np.cross(ey, up)
            # the tube's axis runs through the shoulder tip, along the arm; the cap peak at the tip
            pl = Placement(sh + Rs * up + 0.02 * ey, ex, ey, u0=0.0, v0=Lu + cap_h, radius=Rs)
            if Lu >= 0.35:   # long sleeves follow the arm's bend at the elbow
                el = lm.elbow_left if side == "left" else lm.elbow_right
                wr = lm.wrist_left if side == "left" else lm.wrist_right
                # the shoulder tip is on top of the arm: its axis starts R/2 lower
                pl = ArmTube(np.array([sh + 0.02 * ey - 0.5 * Rs * up, el, wr]), Rs, v0=Lu + cap_h)
            panels.append(PanelSpec(f"sleeve_{side}", Vs, pl, curves=dict(cs), boundary={0: f"sleeve_{side}"}))
        # u > 0 of the left sleeve faces the back (ex = ey × up ≈ −Z), of the right one the front
        seams += [SeamSpec("sleeve_left", 1, "sleeve_left", 4), SeamSpec("sleeve_right", 1, "sleeve_right", 4),
                  SeamSpec("sleeve_left", 3, "front", 2), SeamSpec("sleeve_left", 2, "back", 6),
                  SeamSpec("sleeve_right", 2, "front", 6), SeamSpec("sleeve_right", 3, "back", 2)]
    return PatternSpec(name, panels, seams)


@dataclass
class ArmTube:
    """Places a sleeve panel as a tube of radius R around a bent arm axis (polyline from the
    shoulder through the elbow to the wrist, extended straight beyond it): the panel's v runs
    along the axis (v0 at the first axis point, decreasing away from it), u around it (θ = u/R,
    u = 0 on the top of the arm), as Placement's cylinder for a straight arm; the tube's
    direction turns smoothly over ±`bend` m around each joint."""
    axis: np.ndarray            # (K, 3) m
    radius: float
    v0: float
    bend: float = 0.05

    def __call__(self, uv: np.ndarray) -> np.ndarray:
        P = np.asarray(self.axis, float)
        seg = np.diff(P, axis=0)
        L = np.linalg.norm(seg, axis=1)
        t = seg / L[:, None]
        c = np.concatenate([[0.0], np.cumsum(L)])
        d = np.maximum(self.v0 - uv[:, 1], 0.0)
        k = np.clip(np.searchsorted(c, d, side="right") - 1, 0, len(seg) - 1)
        point = P[k] + (d - c[k])[:, None] * t[k]
        e = t[k].copy()
        for j in range(1, len(seg)):             # smooth turn of the direction at joint j
            lam = np.clip((d - (c[j] - self.bend)) / (2 * self.bend), 0.0, 1.0)[:, None]
            lam = lam * lam * (3 - 2 * lam)
            near = np.abs(d - c[j]) < self.bend
            e[near] = ((1 - lam) * t[j - 1] + lam * t[j])[near]
        ey = -e / np.linalg.norm(e, axis=1, keepdims=True)
        up = np.array([0.0, 1.0, 0.0])[None, :] - ey[:, 1:2] * ey
        up /= np.linalg.norm(up, axis=1, keepdims=True)
        ex = np.cross(ey, up)
        th = uv[:, 0] / self.radius
        return point + self.radius * (np.sin(th)[:, None] * ex + np.cos(th)[:, None] * up)


def _solve_cap_height(Wb: float, target: float, tol: float = 1e-12) -> float:
    """Cap height (m) whose half-cap curve (as drawn in _top_spec) has the armhole's length
    (target, m): the root of a length increasing with the height, bracketed in [0.01, 1] m and
    found to tol (m) by the Illinois variant of false position — about ten curve lengths where
    bisection needed sixty (the measurement fit re-draws the pattern hundreds of times).
    Not scipy's brentq: its heights differ by up to 2e-13 m, and that round-off alone sends the
    template t-shirt's drape into other folds (test_settle, test_fitting's draped t-shirt)."""
    def excess(h):
        p = PanelSpec("c", np.array([[Wb / 2, 0], [0, h], [-Wb / 2, 0]]), None,
                      curves={0: [[Wb / 4 + 0.02, 0.75 * h]]})
        return p.edge_length(0) - target
    lo, hi = 0.01, 1.0
    flo, fhi = excess(lo), excess(hi)
    if flo > 0:
        raise ValueError(f"bicep_width {Wb} m is too wide for an armhole of {target:.3f} m")
    if fhi <= 0:
        return hi
    side = 0
    for _ in range(100):
        mid = (lo * fhi - hi * flo) / (fhi - flo)
        if not lo < mid < hi:
            mid = 0.5 * (lo + hi)
        fm = excess(mid)
        if fm == 0:
            return mid
        if fm < 0:
            lo, flo = mid, fm
            if side < 0:
                fhi *= 0.5   # the same end kept twice: halve its weight (Illinois)
            side = -1
        else:
            hi, fhi = mid, fm
            if side > 0:
                flo *= 0.5
            side = 1
        if hi - lo <= tol:
            break
    return 0.5 * (lo + hi)


def _skirt_spec(lm: BodyLandmarks, m: SkirtMeasurements) -> PatternSpec:
    Ww = (lm.waist_girth + m.waist_ease) / 2
    Wh = m.hem_width / 2
    L = m.length
    V = np.array([[-Wh / 2, 0], [Wh / 2, 0], [Ww / 2, L], [-Ww / 2, L]])
    curves = {2: [[0.0, L - 0.015]]}
    top = lm.waist_center[1] + 0.02
    torso = _torso_section(lm, m.gap, lm.waist_girth + m.waist_ease, lm.hip_girth + m.waist_ease)
    front = PanelSpec("front", V, None, curves=dict(curves), boundary={0: "hem", 2: "waist"})
    back = PanelSpec("back", V, None, curves=dict(curves), boundary={0: "hem", 2: "waist"})
    for p, sgn in ((front, 1.0), (back, -1.0)):
        p.placement = HalfWrap(p, sgn, top - L, (front, back), torso, lm.hip_center[1])
    return PatternSpec("skirt", [front, back], [SeamSpec("front", 1, "back", 3), SeamSpec("front", 3, "back", 1)])


def _torso_section(lm: BodyLandmarks, gap: float, waist: float, hip: float):
    """y → (centre x, centre z, half width, half depth) m of an ellipse around the torso between the
    waist and the hips (constant below the hips), centred on the body's hip → waist centres
    wherever the body stands, for a garment of these girths (m): half width from the body's girth
    (torso_radius) plus gap, depth matching the garment's girth but at least 0.85 × the width
    (deep enough for the seat and the belly)."""
    hip_y, waist_y = lm.hip_center[1], lm.waist_center[1]
    hip_half, waist_half = torso_radius(lm, lm.hip_girth), torso_radius(lm, lm.waist_girth)

    def torso(y):
        t = np.clip((np.asarray(y, float) - hip_y) / (waist_y - hip_y), 0.0, 1.0)
        a = (1 - t) * hip_half + t * waist_half + gap
        girth = (1 - t) * hip + t * waist
        b = np.array([_ellipse_depth(float(ai), float(gi)) for ai, gi in zip(np.atleast_1d(a), np.atleast_1d(girth))])
        cx = (1 - t) * lm.hip_center[0] + t * lm.waist_center[0]
        cz = (1 - t) * lm.hip_center[2] + t * lm.waist_center[2]
        return cx, cz, a, np.maximum(b, 0.85 * a)
    return torso


@dataclass
class HalfWrap:
    """Places a front (front=+1, ex = +X) or back (−1, ex = −X) panel of a skirt: every
    horizontal line of the panel (v up from y = hem_y) on the front or back half of an ellipse
    around the torso at its height (`torso`, see _torso_section), side seams at the sides; below
    the hips the ellipse widens to a circle as long as the garment's width there (front + back
    panel widths) so a flared hem is laid out at its length."""
    panel: PanelSpec
    front: float
    hem_y: float
    pair: tuple                 # the panels whose widths make the garment's girth
    torso: object
    hip_y: float

    def __call__(self, uv: np.ndarray) -> np.ndarray:
        u, v = uv[:, 0], uv[:, 1]
        y = self.hem_y + v
        u0, u1 = _panel_span(self.panel, v)
        s = np.clip((u - u0) / np.maximum(u1 - u0, 1e-9), 0.0, 1.0)
        cx, cz, a, b = self.torso(y)
        girth = sum(np.subtract(*_panel_span(p, v)[::-1]) for p in self.pair)
        r = girth / (2 * np.pi)
        below = y < self.hip_y
        a = np.where(below, np.maximum(a, r), a)
        b = np.where(below, np.maximum(b, r), b)
        psi = -0.5 * np.pi + np.pi * s
        return np.column_stack([cx + self.front * a * np.sin(psi), y, cz + self.front * b * np.cos(psi)])


@dataclass
class PantsMeasurements:
    """Garment measurements of trousers (m). The crotch sits `crotch_drop` below the body's
    (estimated from the hip and knee landmarks); the hem `hem_above_ankle` above the ankle."""
    waist_ease: float = 0.04
    hip_ease: float = 0.10
    crotch_drop: float = 0.04
    front_extension: float = 0.06     # crotch extension of the front panels past the centre line
    back_extension: float = 0.11
    front_rise_curve: float = 0.08    # height of the crotch curve above the crotch point
    back_rise_curve: float = 0.10
    hem_width: float = 0.42           # leg opening circumference
    hem_above_ankle: float = 0.15     # ankle-crop: a hem resting on the feet did not drape clean
    side_taper: float = 0.02          # side seam inward from the hip line at the hem
    gap: float = 0.03


def _panel_span(panel: PanelSpec, v: np.ndarray) -> tuple:
    """(u_min, u_max) of the panel outline on the horizontal lines at heights v (pattern m)."""
    P = np.vstack([panel.edge_polyline(k, 100)[:-1] for k in range(len(panel.vertices))])
    a, b = P, np.roll(P, -1, axis=0)
    lo, hi = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
    vq = np.clip(v, P[:, 1].min(), P[:, 1].max())[:, None]
    hit = (vq >= lo[None]) & (vq <= hi[None]) & (hi > lo)[None]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = a[None, :, 0] + (vq - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (b[None, :, 1] - a[None, :, 1])
    return np.where(hit, u, np.inf).min(1), np.where(hit, u, -np.inf).max(1)


@dataclass
class LegPlacement:
    """3D placement of a trouser panel (front/back × left/right leg; pattern u from the centre
    line towards the body's side, v up from the hem). Every horizontal line of the panel is
    laid on a half cross-section at its height: below the crotch the front (back) half of a
    circle around the leg axis whose circumference is the trouser leg's width there (inseam
    at the inner side, side seam at the outer side); above the crotch a quarter of an ellipse
    around the hip/waist centre (centre seam at the middle, side seam at the side), blended
    over `blend` m. Partner seam points land on the same positions."""
    panel: PanelSpec
    side: float                 # +1 left leg (+X), −1 right leg
    front: float                # +1 front, −1 back
    hem_y: float
    crotch_y: float
    leg_axis: object            # y → (x, z) of the leg axis, m (arrays)
    leg_radius: object          # y → m
    torso: object               # y → (centre x, centre z, half width, half depth), m
    mirrored: bool = False      # pattern u runs from the side towards the centre
    blend: float = 0.06

    def __call__(self, uv: np.ndarray) -> np.ndarray:
        u, v = uv[:, 0], uv[:, 1]
        y = self.hem_y + v
        u0, u1 = _panel_span(self.panel, v)
        s = np.clip((u - u0) / np.maximum(u1 - u0, 1e-9), 0.0, 1.0)   # 0 centre/inner → 1 side
        if self.mirrored:
            s = 1.0 - s
        # leg: angle from the inner side (−π/2) over the front (0) to the outer side (π/2)
        ax, az = self.leg_axis(y)
        R = self.leg_radius(y)
        phi = -np.pi / 2 + np.pi * s
        leg = np.column_stack([ax + self.side * R * np.sin(phi), y, az + self.front * R * np.cos(phi)])
        # torso: from the centre line (ψ = 0) to the side (ψ = π/2)
        cx, cz, a, b = self.torso(y)
        psi = 0.5 * np.pi * s
        tor = np.column_stack([cx + self.side * a * np.sin(psi), y, cz + self.front * b * np.cos(psi)])
        w = np.clip((y - self.crotch_y) / self.blend, 0.0, 1.0)[:, None]
        w = w * w * (3 - 2 * w)
        return (1 - w) * leg + w * tor


def _ellipse_depth(a: float, perimeter: float) -> float:
    """Semi-axis b of the ellipse with semi-axis a and this perimeter (Ramanujan), m."""
    lo, hi = 1e-4, max(a, perimeter / np.pi)
    for _ in range(60):
        b = 0.5 * (lo + hi)
        P = np.pi * (3 * (a + b) - np.sqrt((3 * a + b) * (a + 3 * b)))
        lo, hi = (b, hi) if P < perimeter else (lo, b)
    return 0.5 * (lo + hi)


def _pants_spec(lm: BodyLandmarks, m: PantsMeasurements) -> PatternSpec:
    knee, ankle = lm.knee_left, lm.ankle_left
    hip_y, waist_y = lm.hip_center[1], lm.waist_center[1]
    body_crotch = hip_y - 0.1 * (hip_y - knee[1])      # crotch: a tenth of hip→knee below the hip
    hem_y = ankle[1] + m.hem_above_ankle
    crotch_y = body_crotch - m.crotch_drop
    Vw, Vh, Vc = waist_y - hem_y, hip_y - hem_y, crotch_y - hem_y
    if not 0 < Vc < Vh < Vw:
        raise ValueError("landmarks: expected ankle < crotch < hip < waist heights")
    Ww = (lm.waist_girth + m.waist_ease) / 4          # quarter widths (front = back)
    Wh = (lm.hip_girth + m.hip_ease) / 4
    uo = Wh - m.side_taper                            # side seam at the hem
    ui = uo - m.hem_width / 2                         # inseam at the hem
    Lin = np.hypot(ui + m.front_extension, Vc)        # inseam length (front = back)
    Vcb = np.sqrt(Lin ** 2 - (ui + m.back_extension) ** 2)   # back crotch point, a little lower

    def shape(ext, vc, rise, name, side, front):
        # edges: 0 hem, 1 side (hem→hip), 2 side (hip→waist), 3 waist, 4 centre, 5 crotch curve, 6 inseam
        V = np.array([[ui, 0.0], [uo, 0.0], [Wh, Vh], [Ww, Vw], [0.0, Vw], [0.0, vc + rise], [-ext, vc]])
        curves = {2: [[Wh, Vh + 0.6 * (Vw - Vh)]], 5: [[0.0, vc]]}
        opening = "leg_left" if side > 0 else "leg_right"
        boundary = {0: opening, 3: "waist"}
        # u → +X needs ex = +X on the left front / right back (outward normal), else mirror u
        if side * front < 0:
            K = len(V)
            V = V[::-1] * np.array([-1.0, 1.0])
            remap = lambda k: (K - 2 - k) % K          # noqa: E731  old edge k → new edge index
            curves = {remap(k): [[-c[0], c[1]] for c in cv] for k, cv in curves.items()}
            boundary = {remap(k): nm for k, nm in boundary.items()}
            edge = remap
        else:
            edge = lambda k: k                          # noqa: E731
        return V, curves, boundary, edge

    torso = _torso_section(lm, m.gap, lm.waist_girth + m.waist_ease, lm.hip_girth + m.hip_ease)

    panels, edge_of = [], {}
    for side, sname, kn, an in ((1.0, "left", lm.knee_left, lm.ankle_left),
                                (-1.0, "right", lm.knee_right, lm.ankle_right)):
        d = (kn - an) / (kn[1] - an[1])

        def leg_axis(y, an=an, kn=kn, d=d):
            """Leg axis: x on the ankle→knee line, extended; z on it below the knee and
            towards the hip centre's depth above it (thighs run up to the pelvis)."""
            y = np.asarray(y, float)
            t = np.clip((y - kn[1]) / (hip_y - kn[1]), 0.0, 1.0)
            z = np.where(y < kn[1], an[2] + d[2] * (y - an[1]), (1 - t) * kn[2] + t * lm.hip_center[2])
            return an[0] + d[0] * (y - an[1]), z

        pair = []
        for front, fname, ext, vc, rise in ((1.0, "front", m.front_extension, Vc, m.front_rise_curve),
                                            (-1.0, "back", m.back_extension, Vcb, m.back_rise_curve)):
            V, curves, boundary, edge = shape(ext, vc, rise, fname, side, front)
            name = f"{fname}_{sname}"
            panel = PanelSpec(name, V, None, curves=curves, boundary=boundary)
            edge_of[name] = edge
            pair.append((panel, front))

        def leg_radius(y, pair=pair):   # circumference = front + back widths at that height
            w = 0.0
            for pn, _ in pair:
                u0, u1 = _panel_span(pn, np.asarray(y) - hem_y)
                w = w + (u1 - u0)
            return w / (2 * np.pi)
        for panel, front in pair:
            panel.placement = LegPlacement(panel, side, front, hem_y, crotch_y, leg_axis, leg_radius, torso,
                                           mirrored=side * front < 0)
            panels.append(panel)

    def S(a, ea, b, eb):
        return SeamSpec(a, edge_of[a](ea), b, edge_of[b](eb))
    seams = []
    for sname in ("left", "right"):
        f, b = f"front_{sname}", f"back_{sname}"
        seams += [S(f, 1, b, 1), S(f, 2, b, 2), S(f, 6, b, 6)]      # side seams, inseam
    for fname in ("front", "back"):
        l, r = f"{fname}_left", f"{fname}_right"
        seams += [S(l, 4, r, 4), S(l, 5, r, 5)]                      # centre seam and crotch
    return PatternSpec("pants", panels, seams)


TEMPLATES = {
    "tshirt": "short-sleeve t-shirt, hip length",
    "polo": "polo shirt: the t-shirt with a stand-up collar band and a centre-front placket",
    "longsleeve": "long-sleeve shirt",
    "dress": "short-sleeve dress, knee length, flared",
    "skirt": "A-line skirt, knee length",
    "pants": "trousers, cropped above the ankle (two legs, front and back panels each)",
}


def _split_quadratic(P0, P1, P2, t):
    """Control points of the quadratic Bézier P0-P1-P2 on [0, t] and on [t, 1] (de Casteljau)."""
    P0, P1, P2 = (np.asarray(p, float) for p in (P0, P1, P2))
    A, B = (1 - t) * P0 + t * P1, (1 - t) * P1 + t * P2
    M = (1 - t) * A + t * B
    return (P0, A, M), (M, B, P2)


def _polo_spec(lm: BodyLandmarks, m: TopMeasurements, collar_height: float = 0.04,
               placket_width: float = 0.03, placket_length: float = 0.12) -> PatternSpec:
    """The t-shirt with a collar band and a centre-front placket (m).

    Placket: a notch placket_width wide, reaching placket_length below the neckline, is cut out
    of the front at the centre of its neckline (the neckline is a quadratic Bézier whose x is
    linear in t, so it is split exactly at x = ±width/2) and a placket panel of the notch's
    shape is sewn into it (sides and bottom), placed where the notch was; its top edge is part
    of the neckline the collar is sewn to.
    Collar: a band whose lower edge, split where the front neckline, the placket top and the
    back neckline meet, is sewn along them (right → left along the front, left → right along
    the back); its ends meet in a seam at the right neck point; its upper edge is the neckline
    opening. Placed as a ring around the neck (radius: neckline length / 2π) whose front centre
    faces +Z."""
    spec = _top_spec("polo", lm, m)
    front, back = spec.panels[0], spec.panels[1]
    # front: edge 4 (neckline, +x → −x) becomes 4 (to the notch), 5 notch side down, 6 notch
    # bottom, 7 notch side up, 8 (from the notch on); the front's edges k ≥ 5 move to k + 4
    V = np.asarray(front.vertices, float)
    P0, P2, P1 = V[4], V[5], np.asarray(front.curves[4], float).reshape(2)
    N = P0[0] - P2[0]
    w, d = placket_width, placket_length
    t1, t2 = 0.5 - w / (2 * N), 0.5 + w / (2 * N)
    (a0, a1, _), _ = _split_quadratic(P0, P1, P2, t1)
    _, (b0, b1, b2) = _split_quadratic(P0, P1, P2, t2)
    c1 = _split_quadratic(P0, P1, P2, t1)[0][2]
    yt, yb = c1[1], c1[1] - d
    front.vertices = np.vstack([V[:5], [[w / 2, yt], [w / 2, yb], [-w / 2, yb], [-w / 2, yt]], V[5:]])
    front.curves = {(k + 4 if k >= 5 else k): c for k, c in front.curves.items() if k != 4}
    front.curves[4] = [a1.tolist()]
    front.curves[8] = [b1.tolist()]
    front.boundary = {0: "hem"}
    back.boundary = {0: "hem"}
    remap = lambda panel, e: (e + 4 if panel == "front" and e >= 5 else e)
    spec.seams = [SeamSpec(s.panel_a, remap(s.panel_a, s.edge_a), s.panel_b, remap(s.panel_b, s.edge_b), s.reverse)
                  for s in spec.seams]
    Vp = np.array([[-w / 2, yb], [w / 2, yb], [w / 2, yt], [-w / 2, yt]])
    placket = PanelSpec("placket", Vp, front.placement, grain=front.grain)
    # collar: lower edge = front right part (edge 8), placket top, front left part (edge 4), back
    fa, fb = front.edge_length(8), front.edge_length(4)
    b = back.edge_length(4)
    a = fa + w + fb
    h = collar_height
    Vc = np.array([[0.0, 0.0], [fa, 0.0], [fa + w, 0.0], [a, 0.0], [a + b, 0.0], [a + b, h], [0.0, h]])
    R = (a + b) / (2 * np.pi)
    nb = lm.neck_base
    place = Placement([nb[0], nb[1] + 0.01, nb[2] + R], [1, 0, 0], [0, 1, 0], u0=a / 2, v0=0.0, radius=R)
    collar = PanelSpec("collar", Vc, place, boundary={5: "neckline"}, grain=0.0)
    spec.panels += [placket, collar]
    spec.seams += [SeamSpec("placket", 0, "front", 6), SeamSpec("placket", 1, "front", 5),
                   SeamSpec("placket", 3, "front", 7),
                   SeamSpec("collar", 0, "front", 8), SeamSpec("collar", 1, "placket", 2),
                   SeamSpec("collar", 2, "front", 4), SeamSpec("collar", 3, "back", 4),
                   SeamSpec("collar", 4, "collar", 6)]
    return spec


# the measurements a recovery fits first (pipeline/measurement_fit.py), per built-in template
FIT_MEASUREMENTS = {"tshirt": ("length", "ease", "sleeve_length", "bicep_width"),
                    "polo": ("length", "ease", "sleeve_length", "bicep_width"),
                    "longsleeve": ("length", "ease", "sleeve_length", "bicep_width"),
                    "dress": ("length", "ease", "hem_flare", "sleeve_length"),
                    "skirt": ("length", "waist_ease", "hem_width"),
                    "pants": ("waist_ease", "hip_ease", "hem_width", "hem_above_ankle")}


def template_measurements(name: str, landmarks: BodyLandmarks | None = None, **measurements):
    """The measurements dataclass (m) of a built-in template: its defaults on these landmarks,
    overridden by `measurements`."""
    lm = landmarks or default_landmarks()
    if name == "tshirt":
        return replace(TopMeasurements(), **measurements)
    if name == "polo":
        return replace(TopMeasurements(neck_width=0.18, front_neck_depth=0.06), **measurements)
    if name == "longsleeve":
        return replace(TopMeasurements(sleeve_length=0.58, bicep_width=0.34, cuff_width=0.24, fold_radius=0.17),
                       **measurements)
    if name == "dress":
        return replace(TopMeasurements(length=lm.neck_base[1] - lm.knee_left[1] + 0.02, hem_flare=0.12, ease=0.08,
                                       fold_radius=0.17), **measurements)
    if name == "skirt":
        return replace(SkirtMeasurements(), **measurements)
    if name == "pants":
        return replace(PantsMeasurements(), **measurements)
    raise ValueError(f"name: unknown template {name!r} (built-ins: {sorted(TEMPLATES)})")


def template_spec(name: str, landmarks: BodyLandmarks | None = None, **measurements) -> PatternSpec:
    """The parametric specification of a built-in template; measurements override defaults."""
    lm = landmarks or default_landmarks()
    m = template_measurements(name, lm, **measurements)
    if name in ("tshirt", "longsleeve", "dress"):
        return _top_spec(name, lm, m)
    if name == "polo":
        return _polo_spec(lm, m)
    if name == "skirt":
        return _skirt_spec(lm, m)
    return _pants_spec(lm, m)


def make_template(name: str, landmarks: BodyLandmarks | None = None, edge_length: float = 0.012,
                  **measurements) -> Garment:
    """A built-in garment, triangulated at ``edge_length`` (m) and placed around the body."""
    return build_garment(template_spec(name, landmarks, **measurements), edge_length=edge_length)
