"""``loosefit view``: sequences in the browser viewer (also ``demo --view``)."""

from __future__ import annotations

import argparse
import time

from loosefit.cli.common import log


def add_parser(sub) -> None:
    p = sub.add_parser(
        "view",
        help="sequences in a 3D viewer in the browser (pip install 'loosefit[viewer]')",
        description="Serve sequences of one garment and motion in a 3D viewer in the browser "
        "(viser): the bodies and garments side by side or overlaid, each shown or hidden; "
        "play, pause, a frame slider, the speed, a camera that follows; the garment coloured "
        "by its distance to a reference sequence, its edge strain or its depth inside the "
        "body, with the frame's RMSE. Nothing needs a display: open the printed URL in any "
        "browser (from another machine: ssh -L PORT:localhost:PORT). Sequences opened "
        "together share one timeline and are refused (naming both) unless they have the "
        "same garment, frame count and frame rate; view others one at a time.",
    )
    p.add_argument(
        "sequences",
        nargs="*",
        metavar="SEQUENCE",
        help="sequence .npz files: animate's, the API's save(), demo's "
        "sequence.npz, a data set's sequences/NAME.npz",
    )
    p.add_argument(
        "--data",
        default=None,
        metavar="DATASET",
        help="a data set folder: with --clip, its simulated clip (shown first)",
    )
    p.add_argument("--clip", default=None, metavar="NAME", help="the clip of --data")
    add_view_args(p)
    p.set_defaults(func=run)


def add_view_args(p: argparse.ArgumentParser) -> None:
    """How the viewer serves and starts (read by ``serve``)."""
    from loosefit.api.data import viewer_colourings

    p.add_argument(
        "--port",
        type=int,
        default=8080,
        help="the first port tried (taken: the next free one, printed)",
    )
    p.add_argument(
        "--host", default="127.0.0.1", help="the address to listen on (0.0.0.0: every interface)"
    )
    p.add_argument(
        "--colour",
        default="plain",
        choices=tuple(viewer_colourings()),
        help="colour the garment by: its distance to the reference (error), edge "
        "strain, or depth inside the body (changeable in the panel)",
    )
    p.add_argument(
        "--reference",
        type=int,
        default=0,
        help="the sequence the distance and RMSE are measured to (0: the first)",
    )
    p.add_argument(
        "--overlay",
        action="store_true",
        help="overlaid rather than side by side (changeable in the panel)",
    )
    p.add_argument("--paused", action="store_true", help="start paused")
    p.add_argument(
        "--pixel-ratio",
        type=float,
        default=None,
        help="the canvas's pixels per screen pixel, fixed (e.g. 0.5 for a browser drawing "
        "WebGL without a GPU: a quarter of the pixels, a frame drawn in about 40%% less time; "
        "start Chromium with --webgl-antialiasing-mode=none as well; default: the "
        "browser's, lowered by viser while frames are slow)",
    )


def run(args: argparse.Namespace) -> int:
    """Sequences (and a data set's clip) in the browser viewer, served until Ctrl-C."""
    from loosefit.api.data import read_sequences

    seqs, labels, sources = read_sequences(args.sequences, args.data, args.clip)
    serve(seqs, labels, sources, args)
    return 0


def serve(seqs, labels, sources, args: argparse.Namespace) -> None:
    """Pose the bodies, start the viewer, print its URL and serve until interrupted."""
    from loosefit.api import tqdm_bar
    from loosefit.api.data import open_viewer, viewer_config

    config = viewer_config(  # checked before minutes of posing
        len(seqs),
        host=args.host,
        port=args.port,
        colouring=args.colour,
        layout="overlaid" if args.overlay else "side by side",
        reference=args.reference,
        play=not args.paused,
        pixel_ratio=args.pixel_ratio,
    )
    frames = sum(s.num_frames for s in seqs)
    log(f"{len(seqs)} sequence(s), {seqs[0].num_frames} frames each: posing the bodies")
    bar = tqdm_bar("pose", unit="frame")
    t = time.perf_counter()
    viewer = open_viewer(seqs, labels, config, sources, progress=bar.progress)
    bar.close()
    moved = f" (port {args.port} is in use)" if viewer.port != args.port else ""
    log(f"ready in {time.perf_counter() - t:.1f} s ({frames} frames)")
    print(f"loosefit viewer: {viewer.url}{moved}  (Ctrl-C to stop)", flush=True)
    viewer.wait()
