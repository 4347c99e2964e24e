"""Built-in parametric garment templates (the project's own), defined from body measurements
and placed around a body given by its BodyLandmarks (metres; Y up, body faces +Z, +X is the
body's left).

Tops (t-shirt, long-sleeve, short-sleeve dress) are a front and a back panel wrapped around a
vertical cylinder about the torso a few cm outside the chest, and one sleeve panel per arm
wrapped into a tube around the arm axis (underarm seam closed, cap sewn to the front and back
armholes). The skirt is a front and a back panel wrapped around the hips. Every sewn pair of
edges has the same length in the pattern (the sleeve cap height is solved for it), so the
seam-length regularizer is zero at the template. All lengths below are in metres."""
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
    fold_radius: float = 0.17        # bend of the panels over the shoulders (placement only)


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
    fold = dict(radius=Rt, fold_at=Ls, fold_radius=m.fold_radius)
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
            panels.append(PanelSpec(f"sleeve_{side}", Vs, pl, curves=dict(cs), boundary={0: f"sleeve_{side}"}))
        # u > 0 of the left sleeve faces the back (ex = ey × up ≈ −Z), of the right one the front
        seams += [SeamSpec("sleeve_left", 1, "sleeve_left", 4), SeamSpec("sleeve_right", 1, "sleeve_right", 4),
                  SeamSpec("sleeve_left", 3, "front", 2), SeamSpec("sleeve_left", 2, "back", 6),
                  SeamSpec("sleeve_right", 2, "front", 6), SeamSpec("sleeve_right", 3, "back", 2)]
    return PatternSpec(name, panels, seams)


def _solve_cap_height(Wb: float, target: float) -> float:
    """Cap height (m) whose half-cap curve (as drawn in _top_spec) has the armhole's length."""
    def half_len(h):
        p = PanelSpec("c", np.array([[Wb / 2, 0], [0, h], [-Wb / 2, 0]]), None,
                      curves={0: [[Wb / 4 + 0.02, 0.75 * h]]})
        return p.edge_length(0)
    lo, hi = 0.01, 1.0
    if half_len(lo) > target:
        raise ValueError(f"bicep_width {Wb} m is too wide for an armhole of {target:.3f} m")
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if half_len(mid) < target else (lo, mid)
    return 0.5 * (lo + hi)


def _skirt_spec(lm: BodyLandmarks, m: SkirtMeasurements) -> PatternSpec:
    Ww = (lm.waist_girth + m.waist_ease) / 2
    Wh = m.hem_width / 2
    L = m.length
    V = np.array([[-Wh / 2, 0], [Wh / 2, 0], [Ww / 2, L], [-Ww / 2, L]])
    curves = {2: [[0.0, L - 0.015]]}
    R = max(torso_radius(lm, lm.hip_girth), Wh / np.pi) + m.gap
    axis = lm.hip_center
    top = lm.waist_center[1] + 0.02
    front = PanelSpec("front", V, Placement([axis[0], top - L, axis[2] + R], [1, 0, 0], [0, 1, 0], radius=R),
                      curves=dict(curves), boundary={0: "hem", 2: "waist"})
    back = PanelSpec("back", V, Placement([axis[0], top - L, axis[2] - R], [-1, 0, 0], [0, 1, 0], radius=R),
                     curves=dict(curves), boundary={0: "hem", 2: "waist"})
    return PatternSpec("skirt", [front, back], [SeamSpec("front", 1, "back", 3), SeamSpec("front", 3, "back", 1)])


TEMPLATES = {
    "tshirt": "short-sleeve t-shirt, hip length",
    "longsleeve": "long-sleeve shirt",
    "dress": "short-sleeve dress, knee length, flared",
    "skirt": "A-line skirt, knee length",
}


def template_spec(name: str, landmarks: BodyLandmarks | None = None, **measurements) -> PatternSpec:
    """The parametric specification of a built-in template; measurements override defaults."""
    lm = landmarks or default_landmarks()
    if name == "tshirt":
        return _top_spec(name, lm, replace(TopMeasurements(), **measurements))
    if name == "longsleeve":
        base = TopMeasurements(sleeve_length=0.58, bicep_width=0.34, cuff_width=0.24)
        return _top_spec(name, lm, replace(base, **measurements))
    if name == "dress":
        base = TopMeasurements(length=lm.neck_base[1] - lm.knee_left[1] + 0.02, hem_flare=0.12, ease=0.08)
        return _top_spec(name, lm, replace(base, **measurements))
    if name == "skirt":
        return _skirt_spec(lm, replace(SkirtMeasurements(), **measurements))
    raise ValueError(f"name: unknown template {name!r} (built-ins: {sorted(TEMPLATES)})")


def make_template(name: str, landmarks: BodyLandmarks | None = None, edge_length: float = 0.012,
                  **measurements) -> Garment:
    """A built-in garment, triangulated at ``edge_length`` (m) and placed around the body."""
    return build_garment(template_spec(name, landmarks, **measurements), edge_length=edge_length)
