"""A central difference of an objective whose drapes are equilibria of a non-convex energy,
shared by the pipeline's gradient tests. Newton from a fixed warm start can land the two sides,
or the centre, on different equilibria (under 1e-13 m of pattern round-off: the skirt's pose at
−1e-6 rad, φ 1e-5 lower; the centre of a body-shape difference 1.3 mm from both sides; a skirt
measurement's side on a fold state 1 cm away, φ 3e-4 higher). A difference across two branches
is no derivative."""
import numpy as np

BRANCH_TOL = 1e-4   # m: drapes closer than this are on one branch


def branch_difference(evaluate, h: float, x_centre, an_centre: float):
    """evaluate(s) -> (φ, the adjoint's dφ/dθ_k, drape (V, 3) m) at θ + s e_k. Returns (central
    difference, the adjoint derivative of the same branch, the two sides' drape gap m): steps h,
    then h/3 if the sides' drapes are more than BRANCH_TOL apart; the adjoint's at the centre, or
    the mean of the two sides' (O(h²) from the branch's at the centre) when the centre's drape is
    on another branch."""
    for step in (h, h / 3):
        vp, gp, xp = evaluate(step)
        vm, gm, xm = evaluate(-step)
        gap = float(np.abs(xp - xm).max())
        if gap <= BRANCH_TOL:
            break
    off = max(np.abs(xp - x_centre).max(), np.abs(xm - x_centre).max())
    an = an_centre if off <= BRANCH_TOL else 0.5 * (gp + gm)
    return (vp - vm) / (2 * step), an, gap


def differences_on_one_branch(centre, side, checks, warm):
    """centre(warm) -> (the adjoint's gradient {group: array}, drape (V, 3) m) at θ from the warm
    start `warm`; side(warm, group, k, s) -> (φ, the adjoint's dφ/dθ[group][k], drape) at
    θ + s e_(group, k); checks(gradient) -> [(group, k, h)]. Returns ([(group, k, central difference,
    adjoint, gap)] per check — branch_difference's —, the centre's gradient), all from `warm`, or all again
    from the centre's own drape where some check's sides stay on two branches at h and h/3: θ then
    sits at a basin boundary of Newton from `warm` (round-off seed 17's measurement point: sides
    1 cm apart at every step) and φ, whose contact planes are those detected at the warm start, has
    no derivative there. The centre's drape is the warm start the optimizer's next iteration uses."""
    for _ in range(2):
        grad, x_centre = centre(warm)
        diffs = [(group, k, *branch_difference(lambda s, g=group, k=k: side(warm, g, k, s), h, x_centre,
                                                grad[group][k]))
                 for group, k, h in checks(grad)]
        if all(d[-1] <= BRANCH_TOL for d in diffs):
            break
        warm = x_centre
    return diffs, grad
