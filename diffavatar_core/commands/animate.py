"""`diffavatar animate [RESULT_DIR] --motion walk --frames N --out DIR`: simulate a draped garment
through a body motion. With RESULT_DIR (a `diffavatar recover` output): the recovered pattern as
rest shape, the recovered material and body, starting from the recovered drape (paper §5.5);
without it: --garment, a built-in template draped on the default body. Writes the OBJ sequence,
animation.glb, positions.npz, a contact sheet of frames and animate.json."""
import json


def register(sub) -> None:
    from ..animate import MOTIONS
    p = sub.add_parser("animate", help="simulate recovered assets (or a template on the default body) in a motion")
    p.add_argument("result_dir", nargs="?", default=None, help="a `diffavatar recover` output directory")
    p.add_argument("--garment", default="tshirt", help="a built-in template (diffavatar templates)")
    p.add_argument("--motion", default="walk", help=f"one of {', '.join(MOTIONS)} or a keyframe JSON file")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--cycles", type=float, default=1.0, help="motion periods over the frames")
    p.add_argument("--edge", type=float, default=0.03, help="garment mesh edge length (m)")
    p.add_argument("--out", required=True)
    p.set_defaults(func=_run)


def _run(args) -> int:
    import time

    import numpy as np

    from ..animate import MOTIONS, animate, load_keyframes
    from ..animation_export import write_animation
    from ..body import BodyModel
    from ..render import contact_sheet, orbit_cameras, render
    from ..sim import drape_job
    from . import check_out_dir, write_failed
    t0 = time.perf_counter()
    out = check_out_dir(args.out)   # before the simulation, not after
    motion = args.motion if args.motion in MOTIONS else load_keyframes(args.motion)
    if args.result_dir:
        from ..pipeline.assets import load_result
        assets = load_result(args.result_dir)
        cloth, g = assets.cloth(), {"faces": assets.garment.faces}
        model, params = assets.body_model, assets.body_params
        # the recovered drape is an equilibrium of these assets: Newton polishes it, no XPBD settling
        r = cloth.drape(max_steps=1, min_steps=1, raise_on_divergence=False)
        source = str(args.result_dir)
    else:
        cloth, g, _ = drape_job.build(args.garment, edge=args.edge)
        cloth.sew()
        r = cloth.drape(max_steps=600, raise_on_divergence=False)
        model = BodyModel.default()
        params = model.zero_params()
        source = args.garment
    res = animate(cloth, model, params, motion, args.frames, fps=args.fps, cycles=args.cycles)
    try:
        out.mkdir(parents=True, exist_ok=True)
        files = write_animation(out, res.garment, g["faces"], res.body, model.faces, fps=args.fps)
        cams = orbit_cameras([(res.body[0], model.faces), (res.garment[0], g["faces"])], views=("front",))
        picks = np.linspace(0, args.frames - 1, min(8, args.frames)).astype(int)
        images = [render([(res.body[i], model.faces, (0.85, 0.7, 0.6)), (res.garment[i], g["faces"], (0.3, 0.5, 0.85))],
                         cams["front"], 192) for i in picks]
        contact_sheet(images, out / "frames.png", labels=[f"frame {i}" for i in picks])
        info = {"garment": source, "motion": args.motion, "frames": args.frames, "fps": args.fps,
                "cycles": args.cycles,
                "drape_converged": r.converged, "max_penetration_mm": 1e3 * res.max_penetration,
                "max_distance_from_body_m": res.max_distance, "glb": str(files["glb"]),
                "wall_s": time.perf_counter() - t0}
        (out / "animate.json").write_text(json.dumps(info, indent=2))
    except OSError as exc:   # disk full, the directory removed meanwhile, ...: named, not a traceback
        raise write_failed(args.out, exc, "writing the animation") from None
    print(json.dumps(info, indent=2))
    return 0
