"""`nvr-editor`: open the editor on a scene, or run it headless for tests and screenshots.

    nvr-editor [SCENE.json] [--model WEIGHTS] [--screenshot OUT.png] [--export OUT.png]
               [--export-side-by-side OUT.png] [--force] [--frames N] [--replay ACTIONS.json]

With --frames the window draws at least N frames, plays the replay file, waits until every
job and render has finished, saves the screenshot and exports, prints the UI frame rate and
exits 0 (2 on a user error such as a missing scene file, or an output file that exists
without --force).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from renderer.errors import InputError

DEFAULT_SCENE = Path(__file__).resolve().parents[2] / "assets" / "demo" / "scene.json"
WINDOW_SIZE = (1280, 800)
# A headless run still busy after this long gives up (NVR_EDITOR_TIMEOUT overrides, in seconds).
IDLE_TIMEOUT_SECONDS = float(os.environ.get("NVR_EDITOR_TIMEOUT", 300.0))
IDLE_WAIT_SECONDS = 0.5  # with nothing going on, the loop sleeps until input arrives (at most this long)
ACTIVE_AFTER_INPUT_SECONDS = 0.5  # keep drawing at full rate this long after the last input event
EXIT_USER_ERROR = 2


def build_parser() -> argparse.ArgumentParser:
    from app.cli import OneLineParser
    from models.renderers import INTERACTIVE

    p = OneLineParser(prog="nvr-editor", description="NVR Studio editor: voxel viewport and live neural render.")
    p.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE), help="scene file (default: the demo scene)")
    p.add_argument("--renderer", choices=list(INTERACTIVE), default=None,
                   help="the render panel's renderer (default: nvr+, which shows the shaded image while a drag "
                        "lasts); switch in the panel")
    p.add_argument("--model", default=None, help="NVR+ weights (.safetensors); default: the shipped model")
    p.add_argument("--quality", choices=["full", "fast"], default="full",
                   help="the live render's voxel shader: full, as the network was trained; fast: one ray per "
                        "silhouette pixel, 2 x 2 light points, normals from the smoothed field alone, one voxel's "
                        "color a point, no ambient occlusion, for slower CPUs (exports stay full)")
    p.add_argument("--frames", type=int, default=None, help="headless: draw at least N frames, then exit when idle")
    p.add_argument("--replay", default=None, help="JSON list of actions to perform (see app/editor/replay.py)")
    p.add_argument("--screenshot", default=None, help="with --frames: save the whole window as PNG at the end")
    p.add_argument("--export", default=None, help="save the render (as the panel's renderer makes it) as PNG before exiting")
    p.add_argument("--export-side-by-side", default=None, metavar="OUT.png",
                   help="save the viewport and the neural render side by side as PNG before exiting")
    p.add_argument("--force", action="store_true", help="overwrite output files that exist")
    return p


def run(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from app.editor.window import Window, WindowError
    from models.threads import limit_blas_threads

    limit_blas_threads()

    try:
        document, replay = _load_inputs(args)
    except InputError as exc:
        print(f"nvr-editor: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    try:
        window = Window("NVR Studio", *WINDOW_SIZE)
    except WindowError as exc:
        print(f"nvr-editor: error: {exc}", file=sys.stderr)
        return 1
    try:
        return _main_loop(window, document, replay, args)
    finally:
        window.close()


def _load_inputs(args: argparse.Namespace):
    from app.editor.document import Document
    from app.editor.replay import Replay, load_replay
    from renderer.io import check_writable

    if args.frames is not None and args.frames < 1:
        raise InputError(f"--frames must be at least 1, got {args.frames}")
    for output in (args.screenshot, args.export, args.export_side_by_side):
        if output:
            check_writable(output, overwrite=args.force)
    replay = Replay(load_replay(args.replay)) if args.replay else None
    if args.model:
        from models.networks.checkpoint import check_weights_file

        check_weights_file(args.model)  # a refused model file ends the start, rather than a silent fallback
    return Document.open(args.scene), replay


def _main_loop(window, document, replay, args: argparse.Namespace) -> int:
    from app.editor import state
    from app.editor.app import FRAME_SECONDS, EditorApp
    from app.editor.panels import Interface
    from app.editor.render_panel import DETAIL_DELAY_S

    headless = args.frames is not None
    renderer = args.renderer or "nvr+"
    app = EditorApp(window, document, model_path=args.model, renderer=renderer, quality=args.quality,
                    recovery_slot=state.HEADLESS_RECOVERY if headless else state.RECOVERY,
                    detail_delay=0.0 if headless else DETAIL_DELAY_S)
    interface = Interface(app)
    frame, started, finishing = 0, time.monotonic(), False
    try:
        while True:
            wait = 0.0 if headless or _active(app, interface, window) else IDLE_WAIT_SECONDS
            frame_start = time.perf_counter()
            if replay is not None:
                replay.step(app)
            window.begin_frame(wait)
            work_start = time.perf_counter()
            app.update()
            interface.draw()
            drawn = window.end_frame(interface.underlay, interface.images, force=app.screenshots.due)
            app.screenshots.take()
            window.present()
            frame += 1
            if window.close_requested:
                window.keep_open()
                app.request_quit()
            if app.quit_requested or finishing:
                break
            if headless and app.loaded_nothing:
                return EXIT_USER_ERROR  # no object of the start-up scene can be loaded; their errors are printed
            if headless and frame >= args.frames and (replay is None or replay.done) and not app.busy:
                finishing = True  # one more frame, with everything finished, for the screenshot
                if args.screenshot:
                    app.screenshots.request(args.screenshot)
            if headless and time.monotonic() - started > IDLE_TIMEOUT_SECONDS:
                print(f"nvr-editor: error: still busy after {IDLE_TIMEOUT_SECONDS:.0f} s: {app.busy}", file=sys.stderr)
                return 1
            work = time.perf_counter() - work_start
            time.sleep(max(0.0, FRAME_SECONDS - (time.perf_counter() - frame_start)))
            if wait == 0.0:
                app.stats.add(time.perf_counter() - frame_start, work, rendering=not app.live.idle, drawn=drawn)
        if args.export and not app.files.export(args.export, overwrite=True):  # checked up front, with --force
            return EXIT_USER_ERROR
        if args.export_side_by_side and not app.files.export_side_by_side(args.export_side_by_side, overwrite=True):
            return EXIT_USER_ERROR
    finally:
        interface.close()
        app.close()
    if headless:
        print(f"nvr-editor: {frame} frames; {app.stats.summary()}")
    return 0


def _active(app, interface, window) -> bool:
    """Whether the next frame must come at once: work under way, a drag, or recent input."""
    return (app.busy or interface.viewport_input.interacting or app.prompt is not None
            or time.monotonic() - window.last_input < ACTIVE_AFTER_INPUT_SECONDS)


def main() -> None:
    sys.exit(run())


if __name__ == "__main__":
    main()
