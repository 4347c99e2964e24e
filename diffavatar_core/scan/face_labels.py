"""Per-face labels → the per-vertex labels the pipeline uses (scan/loading.py converts a PLY's
per-face `label` with face_to_vertex_labels): chosen so that the garment region the pipeline
derives (for garment label g, the faces whose three vertices carry g) matches the faces
labelled g as closely as a per-vertex labelling can."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FaceLabelConversion:
    """What face_to_vertex_labels did: labels (V,) int64 per-vertex labels; faces_off: faces
    whose garment-region status differs from their face label under these vertex labels (a
    per-vertex labelling cannot represent every per-face one: a lone body face amid garment faces,
    say); extra / missing: of those, faces in a garment region their label does not name / faces
    labelled a garment but outside its region; garment_faces: faces labelled a garment."""
    labels: np.ndarray
    faces_off: int
    extra: int
    missing: int
    garment_faces: int


def face_to_vertex_labels(faces: np.ndarray, face_labels: np.ndarray, n_vertices: int,
                          is_garment, max_rounds: int = 10) -> FaceLabelConversion:
    """Per-vertex labels from per-face ones, chosen so that the garment regions the pipeline
    derives from them (for garment label g: the faces whose three vertices carry g) match the
    faces labelled g as closely as a per-vertex labelling can.

    faces (F, 3) int, valid indices; face_labels (F,) int64; is_garment(value) -> bool (which
    labels are garments: the label map's classes). Rule:
      1. a vertex whose faces agree takes their label; where labels meet, a garment label wins
         over a non-garment one (so every garment face keeps its three vertices: none is lost at
         a garment–body border); among several, the label of the most faces (ties: the lowest
         value). A vertex no face uses takes the most common non-garment face label (else the
         most common label);
      2. then, vertex by vertex where a face's region status is off (a body face whose three
         vertices are all on the garment's border, two garments meeting), the label among its
         faces' labels that puts the fewest of its faces off is taken if it puts fewer off than
         the current one (at most max_rounds sweeps; each change strictly lowers the count).
    Labels only take values present in face_labels. Cost O(F log F) plus the local sweeps over
    the border vertices that are off."""
    F = np.asarray(faces, np.int64)
    FL = np.asarray(face_labels, np.int64)
    n = int(n_vertices)
    vals, li = np.unique(FL, return_inverse=True)
    li = li.reshape(-1)
    nL = len(vals)
    garm = np.array([bool(is_garment(int(v))) for v in vals])

    # 1. counts per (vertex, label), garment labels first
    key = F.ravel() * nL + np.repeat(li, 3)
    uk, cnt = np.unique(key, return_counts=True)
    kv, kl = uk // nL, uk % nL
    score = cnt + garm[kl] * (3 * len(F) + 1)          # any garment face outweighs all others
    order = np.lexsort((kl, -score, kv))                # per vertex: best score, then lowest value
    first = order[np.r_[True, kv[order][1:] != kv[order][:-1]]]
    face_count = np.bincount(li, minlength=nL)
    fallback = (np.flatnonzero(~garm)[np.argmax(face_count[~garm])] if (~garm).any()
                else int(np.argmax(face_count)))
    lv = np.full(n, fallback, np.int64)                 # label indices into vals
    lv[kv[first]] = kl[first]

    tgt = np.where(garm[li], li, -1)                    # the garment region each face should be in

    def region(lf):                                     # (k, 3) label indices → region label or -1
        same = (lf[:, 0] == lf[:, 1]) & (lf[:, 1] == lf[:, 2])
        return np.where(same & garm[lf[:, 0]], lf[:, 0], -1)

    def off(reg, t):
        return (reg != t).astype(np.int64) + ((reg != t) & (reg >= 0) & (t >= 0))

    # 2. local improvement where faces are off
    from scipy.sparse import csr_matrix
    vf = csr_matrix((np.ones(3 * len(F), np.int8), (F.ravel(), np.repeat(np.arange(len(F)), 3))),
                    shape=(n, len(F)))
    vf.sort_indices()
    ptr, idx = vf.indptr, vf.indices
    dirty = None                                        # faces near last round's changes
    for _ in range(max_rounds):
        bad = np.flatnonzero(region(lv[F]) != tgt)
        if dirty is not None:
            bad = bad[dirty[bad]]
        if not len(bad):
            break
        changed = []
        for v in np.unique(F[bad].ravel()):
            fs = idx[ptr[v]:ptr[v + 1]]
            lf = lv[F[fs]]
            t = tgt[fs]
            here = F[fs] == v
            cur = int(lv[v])
            best, best_err = cur, int(off(region(lf), t).sum())
            opts, c = np.unique(li[fs], return_counts=True)
            ng = opts[~garm[opts]]                      # one non-garment option: the most common
            ng = [int(ng[np.argmax(c[~garm[opts]])])] if len(ng) else []
            for x in [int(o) for o in opts[garm[opts]][np.argsort(-c[garm[opts]], kind="stable")]] + ng:
                if x == cur:
                    continue
                lf2 = np.where(here, x, lf)
                e = int(off(region(lf2), t).sum())
                if e < best_err:
                    best, best_err = x, e
            if best != cur:
                lv[v] = best
                changed.append(v)
        if not changed:
            break
        dirty = np.zeros(len(F), bool)
        dirty[np.concatenate([idx[ptr[v]:ptr[v + 1]] for v in changed])] = True
    reg = region(lv[F])
    extra = int(np.count_nonzero((reg >= 0) & (reg != tgt)))
    missing = int(np.count_nonzero((tgt >= 0) & (reg != tgt)))
    return FaceLabelConversion(vals[lv], int(np.count_nonzero(reg != tgt)), extra, missing,
                               int(np.count_nonzero(tgt >= 0)))
