"""`pytest --roundoff-seed N`: every built-in template's rest shape (m) gets N(0, (1e-13 m)²)
noise before anything uses it — a stand-in for another CPU's or compiler's round-off. The noise
is a deterministic function of N and the rest shape itself, as round-off is: the same template
gives the same pattern every time within a run.

Cloth drapes are chaotic: which folds a buckled drape settles into can change with the last
bits of the pattern. A test that asserts a property of "the" drape must hold over the fold
states round-off can give, and `make test` runs on whatever CPU CI has. Run the suite with a
few seeds before trusting a bound that sits close to one measurement. Stop 33 found this way
NaN mean value coordinates of a vertex 1e-13 m off its cage edge, a measurement fit that left the
cloth at a rejected trial, and five tests that held in one fold state only (the settled t-shirt,
the draped t-shirt's body fit, a softer truth hanging lower, a reloaded result, and a central
difference whose one side Newton took to another equilibrium). Stop 34 (seeds 10–18): seed 10 found a fixture that carried one test's perturbed cloth into the next two
(now restored after every test) and self-anchoring that converged at a state whose own contact
planes were not the ones it held (a reload moved 0.75 mm; Cloth.self_anchor now re-solves with
them); seed 13 a t-shirt drape that needed 206 Newton iterations where the drape command allowed
200; seed 14 a central difference whose centre Newton took to another equilibrium than its two
sides (test/pipeline/branch_difference.py). Under seed 17 the measurement gradient's test point
(test_measurement_fit) sat next to a basin boundary of Newton from the fixture's drape: at steps
of 1e-6 m and more one side landed on an equilibrium 1 cm away, and below that Newton's tolerance
dominated the difference (11% off at 3.3e-7). Stop 35: the test then takes its differences from
the centre's own drape (the optimizer's next warm start), where they agree to 3e-7. The skirt
fixture's drape is not an equilibrium of the contact planes detected at it (relative residual
~300), and at the test point re-detecting and re-solving alternates between two states 0.86 mm
apart (face contact planes). Seeds 11, 12, 15, 16, 17 and 18 pass. Stop 37: under every seed the
built-in tops' control cages had other handles than the exact templates' (t-shirt, long sleeve
80–89 against 75; the convex hull took noise for corners, test_cage.py), so a seeded recovery of a
top optimized another parametrization (the skirts' and the dress's cages were not affected)."""
import hashlib

import numpy as np

SCALE = 1e-13   # m


def install(seed: int) -> None:
    """Wraps diffavatar_core.pattern.templates.make_template, also where a loaded module has
    imported it by name (pytest_configure runs before collection, a benchmark after its imports)."""
    import sys

    import diffavatar_core.pattern.templates as templates
    original = templates.make_template

    def make_template(*args, **kwargs):
        t = original(*args, **kwargs)
        digest = hashlib.sha256(np.ascontiguousarray(t.rest).tobytes()).digest()
        rng = np.random.default_rng([seed, int.from_bytes(digest[:8], "little")])
        t.rest[...] = t.rest + rng.normal(scale=SCALE, size=t.rest.shape)
        return t

    make_template.__wrapped__ = original
    make_template.__doc__ = original.__doc__
    for module in list(sys.modules.values()):
        if getattr(module, "make_template", None) is original:
            module.make_template = make_template
