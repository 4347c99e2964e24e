"""`diffavatar recover SCAN --out DIR`: the main job — recover the sewing pattern, material and
body from a segmented scan (paper §4.2) and write the result directory (docs/pipeline.md)."""
import contextlib
import json
import pathlib
import signal
import sys
import threading
import time

from ..scan.frame import UP_AXES


def register(sub) -> None:
    p = sub.add_parser("recover", help="recover pattern, material and body from a segmented scan")
    p.add_argument("scan", help="scan mesh: PLY with a per-vertex `label` (segmented) or a garment-only mesh")
    p.add_argument("--out", required=True, help="output directory (result.json, pattern.*, OBJ files, PNGs)")
    p.add_argument("--garment", default=None, help="garment type (a template name or a synonym in "
                   "config/labels.yaml); required for a garment-only scan")
    p.add_argument("--template", default=None, help="template file instead of the built-in one "
                   "(OBJ with UV pattern, or GarmentCode *_specification.json)")
    p.add_argument("--units", default=None, choices=("m", "cm", "mm"), help="units of the scan (default m)")
    p.add_argument("--up", default=None, choices=UP_AXES,
                   help="vertical axis of the scan (default y; a Y-down file: --up=-y)")
    p.add_argument("--iterations", type=int, default=None, help="co-optimization iterations (config: 30)")
    p.add_argument("--output-edge", type=float, default=None, metavar="M",
                   help="edge length (m) of the output mesh when finer than the optimized one: the result is "
                        "carried to it through the control cage and re-draped (config: 0 = off)")
    p.add_argument("--config", default=None, help="YAML merged over config/diffavatar.yaml")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_run)


class ProgressBar:
    """One status line on stderr: stage, iteration, loss, elapsed and ETA of the optimization."""

    def __init__(self, stream=None):
        stream = stream if stream is not None else sys.stderr   # the current one (not the one at import)
        self.stream, self.t0, self.t_opt = stream, time.perf_counter(), None
        self.tty = stream.isatty()

    def __call__(self, stage, iteration, max_iterations, loss, terms):
        now = time.perf_counter()
        line = f"[{now - self.t0:6.1f} s] {stage:<10}"
        if stage == "optimize" and max_iterations:
            if self.t_opt is None:
                self.t_opt = now
            done = iteration / max_iterations
            bar = "#" * int(20 * done) + "-" * (20 - int(20 * done))
            eta = (now - self.t_opt) / iteration * (max_iterations - iteration) if iteration else float("nan")
            line += f" [{bar}] {iteration}/{max_iterations}"
            if loss == loss:
                line += f"  loss {loss:.4g}"
            if eta == eta:
                line += f"  ETA {eta:5.0f} s"
        if self.tty:
            self.stream.write("\r\033[K" + line)
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self):
        if self.tty:
            self.stream.write("\n")


@contextlib.contextmanager
def _sigint_cancels(token, keeping=lambda: False):
    """Ctrl-C (SIGINT) during the recovery cancels `token` — so the candidate drapes running in
    other threads (candidate_workers.py) stop within an iteration too, instead of being waited
    for. While `keeping()` is false it also interrupts the main thread as usual (KeyboardInterrupt:
    cli.main says 'cancelled', exit status 130); once true (the optimization has begun) the first
    Ctrl-C only cancels — the recovery ends at its next check with what it produced
    (RecoveryCancelled), to be written — and a second one interrupts. The previous handler is back
    afterwards; off the main thread, or with SIGINT not at Python's default (ignored, or the
    caller's own handler), nothing changes."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):   # e.g. ignored (a background job)
        yield
        return

    def on_sigint(signum, frame):
        first = not token.cancelled
        token.cancel()
        if not (first and keeping()):
            raise KeyboardInterrupt
    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _run(args) -> int:
    from ..config import load_config
    from . import check_out_dir, write_failed
    check_out_dir(args.out)   # before the minutes of recovery, not after
    from ..pipeline import RecoverOptions, recover
    from ..pipeline.output import write_result
    cfg = load_config(args.config)
    opts = RecoverOptions.from_config(cfg, garment_type=args.garment, template=args.template, units=args.units,
                                      up=args.up, iterations=args.iterations,
                                      output_edge_length=args.output_edge)
    bar = None if args.quiet else ProgressBar()
    from .. import CancelToken
    from ..pipeline.recovery import RecoveryCancelled
    cancel, stages = CancelToken(), set()

    def progress(stage, *rest):
        stages.add(stage)
        if bar is not None:
            bar(stage, *rest)
    cancelled = None
    try:
        with _sigint_cancels(cancel, keeping=lambda: "optimize" in stages):
            result = recover(pathlib.Path(args.scan), opts, progress=progress, cancel=cancel)
    except RecoveryCancelled as exc:   # what the optimization produced until then is kept
        result, cancelled = exc.result, exc
    finally:
        if bar is not None:
            bar.close()
    try:
        out = write_result(result, args.out, scan=result.scan_mesh)
    except OSError as exc:   # disk full, the directory removed meanwhile, ...: named, not a traceback
        raise write_failed(args.out, exc, "writing the recovery's result") from None
    _summary(result, out)
    if cancelled is not None:   # as cli.main's 'diffavatar: cancelled' (exit status 130), saying what was kept
        from ..cli import EXIT_CANCELLED
        print(f"diffavatar: {cancelled}; what it had produced is in {out}/ (result.json: metrics.stopped, "
              f"metrics.cancelled_during, warnings)", file=sys.stderr)
        return EXIT_CANCELLED
    return 0


def _summary(result, out) -> None:
    """The result's summary (JSON) and where its files are, on stdout."""
    m = result.metrics
    fit, sizing = m.get("measurement_fit") or {}, m.get("template_sizing") or {}
    print(json.dumps({
        "output_dir": str(out), "garment_type": result.garment_type, "template": result.template_name,
        "iterations": result.iterations, "stopped": m.get("stopped"), "wall_s": round(result.wall_s, 1),
        "garment_vertices": len(result.garment_vertices),
        "chamfer_initial_cm": round(m["chamfer_initial_cm"], 3), "chamfer_final_cm": round(m["chamfer_final_cm"], 3),
        "bending_stiffness_Nm": result.material.bending_stiffness,
        "bending_stiffness_range_Nm": list(result.material.bending_stiffness_range),   # null: open on that side
        "mesh_quality_min": round(m["mesh_quality_min"], 3),
        "seam_length_mismatch_max_pct": round(m["seam_length_mismatch_max_pct"], 3), "ssim": m.get("ssim"),
        "template_sized_m": {n: round(v, 4) for n, v in (sizing.get("measurements_m") or {}).items()} if sizing.get("kept") else {},
        "template_measurements_m": {n: round(v, 4) for n, v in zip(fit.get("names", []), fit.get("fitted_m", []))},
        "cancelled_during": m.get("cancelled_during"), "warnings": result.warnings}, indent=2))
    print(f"outputs in {out}/: result.json, pattern.json/.svg/.png, garment_rest.obj, garment_draped.obj, "
          f"body.obj, loss.png, preview.png")
