"""The ``ltc`` commands of the tools around the mapper: ``simulate`` (synthetic recordings),
``evaluate`` (a map against ground truth), ``calibrate`` (a detector's measured response) and
``check`` (what an ingest would take from a recording).

Part of the command line (with :mod:`ltc_cli.cli`, whose group they join): the only other code that
prints. Library errors reach the user as one line through the group's handler.
"""

from __future__ import annotations

import json
import sys

import click

from ltc_cli.cli import READER_OPTION_HELP, cli, progress_bar, reader_options, warn_line
from ltc_cli.config import load_config
from ltc_cli.text import plural, skipped_breakdown
from ltc_cli.threads import mapping_threads


# Static (importing the simulator to read its DEFAULTS would slow every ltc command by half a
# second); tests/test_cli_help.py checks it against DEFAULTS.
SIMULATE_OPTIONS_HELP = (
    "A simulator option, repeat for several, e.g. --set miss_rate=0.3. Detector: miss_rate (0.15), "
    "confusion_rate (0.05), false_positive_rate (0.05, per frame), split_rate (0.03), bleed_px (3), "
    "min_pixels (auto: 5e-4 of the image); depth sensor: depth_noise (0.005 m at 1 m), depth_resolution "
    "(0.003), noise_block (8), min_range (0.3), max_range (8.0), rgb_noise (2.0); between laps: "
    "moved_fraction (0.15), removed_fraction (0.1), added_fraction (0.1); robot: frames_per_room (auto), "
    "transit_step (0.8 m), camera_height (1.0 m), camera_pitch_deg (12.0); realistic failure modes (0 in "
    "the benign profile; the realistic profile's value in brackets): pose_drift_m (0 [0.04]), pose_drift_deg "
    "(0 [1.5]), pose_jitter_m (0 [0.005]), pose_jitter_deg (0 [0.2]), drift_frames (15), class_miss (0 [1]), "
    "oblique_miss (0 [0.5]), view_correlation (0 [0.85]), correlation_frames (6), mislabel_objects (0 [0.25]), "
    "mislabel_share (0 [0.35]), phantoms_per_room (0 [1]), cnn_masks (0 [1]), dark_dropout (0 [0.5]), "
    "shiny_dropout (0 [0.25]), flying_pixels (0 [0.5]), size_variation (0 [0.12]), people_per_room (0 [1]).")


@cli.command()
@click.argument("outdir", type=click.Path(file_okay=False))
@click.option("--scene", type=click.Choice(["tiny", "small", "medium", "large"]), default="small", show_default=True,
              help="House size: tiny (1 room, 12 frames a lap, for tests), small (2 rooms), medium (4), large (6).")
@click.option("--laps", type=click.IntRange(1, 100), default=2, show_default=True,
              help="Laps of the same path; between laps objects are moved, removed and added.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Random seed: the same arguments give byte-identical files.")
@click.option("--width", type=click.IntRange(min=16), default=640, show_default=True, help="Image width, pixels.")
@click.option("--height", type=click.IntRange(min=16), default=480, show_default=True, help="Image height, pixels.")
@click.option("--profile", type=click.Choice(["realistic", "benign"]), default="realistic", show_default=True,
              help="realistic: the failure modes of real data (pose drift, per-class and correlated misses, "
                   "systematic mislabels, recurring phantoms, CNN-like masks, depth holes and flying pixels, "
                   "varied sizes, people walking through); benign: independent per-frame detector noise and "
                   "exact poses (how sample_data/ was made). See docs/simulator.md.")
@click.option("--set", "sets", multiple=True, metavar="OPTION=VALUE", help=SIMULATE_OPTIONS_HELP)
def simulate(outdir, scene, laps, seed, width, height, profile, sets):
    """Write a synthetic house as ltc-recording/1 folders OUTDIR/lap1, lap2, ... (with ground truth,
    annotations and a noisy recorded detector)."""
    from ltc_cli.config import parse_set
    from ltc_cli.tools.simulate import simulate as run_simulate

    options = {}
    for item in sets:
        options.update(parse_set(item))
    bar = None

    def progress(done, total):
        nonlocal bar
        if bar is None:
            bar = click.progressbar(length=total, label="simulate", file=sys.stderr)
            bar.__enter__()
        bar.update(1)

    try:
        summary = run_simulate(outdir, scene=scene, laps=laps, seed=seed, width=width, height=height, profile=profile,
                               progress=progress if sys.stderr.isatty() else None, **options)
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    frames = sum(lap["frames"] for lap in summary["laps"])
    click.echo(f"{outdir}: {plural(len(summary['laps']), 'lap')} of the {scene} house (seed {seed}), "
               f"{profile} profile, {plural(frames, 'frame')}, {summary['bytes'] / 1e6:.1f} MB")


def _fmt(v, spec=".3f"):
    return "-" if v is None else format(v, spec)


@cli.command()
@click.argument("map_path", type=click.Path())
@click.option("--ground-truth", "gt_path", required=True, type=click.Path(), help="ground_truth.json, or a recording folder holding one.")
@click.option("--previous", "prev_paths", multiple=True, type=click.Path(), help="An earlier lap's ground truth, to count ghosts; repeat for several laps, oldest first (default: the lap1..lap(N-1) folders beside a lapN recording).")
@click.option("--max-distance", type=float, default=3.0, show_default=True, help="Largest centre distance of a match (m).")
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table", show_default=True)
def evaluate(map_path, gt_path, prev_paths, max_distance, fmt):
    """Compare a map with ground-truth objects (precision, recall, F1 at any overlap and at XY IoU
    0.25 and 0.5, IoU, VIoU, duplicates, ghosts, objects deleted while present)."""
    from ltc_cli.tools.evaluate import evaluate_map
    from ltc_cli.tools.evaluate_report import evaluation_summary, evaluation_table
    from ltc_cli.recordings.groundtruth import earlier_laps, read_ground_truth
    from ltc_cli.map.store import load_map

    smap = load_map(map_path)
    gt = read_ground_truth(gt_path)
    prev = [read_ground_truth(p) for p in prev_paths] if prev_paths else earlier_laps(gt_path)
    res = evaluate_map(smap, gt, prev, max_center_distance=max_distance)
    if fmt == "json":
        click.echo(json.dumps(res, indent=2, default=float))
    else:
        for ln in evaluation_table(res):
            click.echo(ln)
    click.echo(f"{map_path}: {evaluation_summary(res)}", err=(fmt == "json"))


@cli.command("calibrate")
@click.argument("recording", type=click.Path())
@click.option("--detector", help="Detector plugin to measure (default: the config's, recorded).")
@click.option("--config", "config_file", type=click.Path(dir_okay=False), help="YAML file of settings (detector options, maintenance.min_visible_pixels).")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override one setting, e.g. --set detector.options.score_threshold=0.4")
@click.option("-o", "--output", default="calibration.yaml", show_default=True, type=click.Path(dir_okay=False), help="The calibration file to write (atomically).")
@click.option("--min-pixels", type=click.IntRange(min=1), help="Fewest visible pixels of an instance that counts (default: maintenance.min_visible_pixels scaled to the image area).")
@click.option("--iou", "iou_threshold", default=0.5, show_default=True, type=click.FloatRange(0, 1, min_open=True), help="Mask IoU for a detection to match an instance.")
@click.option("--format", "reader", help="Recording reader (default: detected from the folder).")
@click.option("--reader-option", "-r", "reader_opts", multiple=True, metavar="KEY=VALUE", help=READER_OPTION_HELP)
@click.option("--table", is_flag=True, help="Print the per-class figures before the summary.")
def calibrate_cmd(recording, detector, config_file, sets, output, min_pixels, iou_threshold, reader, reader_opts, table):
    """Measure a detector on RECORDING's ground-truth instance masks; write v_Other and the figures."""
    from ltc_cli.recordings.open import count_frames
    from ltc_cli.tools.calibrate import calibrate
    from ltc_cli.tools.calibration_file import write_calibration

    cfg = load_config(config_file, sets)
    if detector:
        cfg["detector"]["name"] = detector
    r_opts = reader_options(reader_opts)
    with progress_bar("calibrate", lambda: count_frames([recording], reader, r_opts)) as progress, mapping_threads():
        cal = calibrate(
            recording, cfg["detector"]["name"], dict(cfg["detector"]["options"]), reader=reader, reader_options=r_opts,
            min_visible_pixels=cfg["maintenance"]["min_visible_pixels"], min_pixels=min_pixels,
            iou_threshold=iou_threshold, progress=progress, warn=warn_line,
        )
    doc = write_calibration(cal, output)
    if table:
        click.echo(f"{'class':<16}{'inst':>6}{'det':>6}{'TP':>6}{'FP':>6}{'FN':>6} {'recall':>7} {'precision':>9} {'v_other':>7}")
        for name, s in doc["per_class"].items():
            click.echo(f"{name[:15]:<16}{s['instances']:>6}{s['detected']:>6}{s['tp']:>6}{s['fp']:>6}{s['fn']:>6} "
                       f"{_fmt(s['recall']):>7} {_fmt(s['precision']):>9} {_fmt(s['v_other']):>7}")
    for w in cal.warnings:
        click.echo(f"warning: {w}", err=True)
    skipped = f" ({cal.frames_skipped} skipped: {skipped_breakdown(cal.skipped_reasons)})" if cal.frames_skipped else ""
    click.echo(
        f"{output}: {plural(cal.frames, 'frame')}{skipped}, {plural(doc['instances'], 'instance')}, "
        f"recall {_fmt(doc['recall'], '.2f')} (any class {_fmt(doc['detection_rate'], '.2f')}), "
        f"precision {_fmt(doc['precision'], '.2f')}, v_other {doc['v_other']:.2f}"
    )


def still_text(counted: dict) -> str:
    """``ltc check``'s line on a still camera's frames (recording_check.still_frames)."""
    from ltc_cli.ingest.keyframes import still_rule

    if counted["move_m"] is None or counted["turn_deg"] is None:
        text = "none: every frame is mapped (frames.still_move or still_turn is null)"
    else:
        text = f"{plural(counted['still'], 'frame')}, not mapped: {still_rule(counted['move_m'], counted['turn_deg'])}"
    return text + (f"; {plural(counted['unknown'], 'frame')} without a readable pose" if counted["unknown"] else "")


@cli.command("check")
@click.argument("recording", type=click.Path())
@click.option("--format", "reader", help="Recording reader (default: detected).")
@click.option("--reader-option", "-r", "reader_opts", multiple=True, metavar="KEY=VALUE", help=READER_OPTION_HELP)
@click.option("--config", "config_file", type=click.Path(dir_okay=False), help="YAML file of settings (the frames and modeling sections).")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override one setting, e.g. --set frames.still_move=null")
@click.option("--frames", "frame_spec", metavar="START:STOP[:STEP]",
              help="Check only this range of its frames, as ltc ingest --frames.")
@click.option("--json", "as_json", is_flag=True, help="Print it as JSON.")
def check_cmd(recording, reader, reader_opts, config_file, sets, frame_spec, as_json):
    """Say what an ingest would take from RECORDING, without mapping it: the camera, the depth range
    and error, the up axis and floor, whether its poses fit its depth, and how many frames a still
    camera's are (a few frames are read; nothing is written)."""
    from ltc_cli.cli import camera_text
    from ltc_cli.ingest.recording_check import check_recording
    from ltc_cli.recordings.open import frame_range, open_recording

    warnings: list = []

    def warn(message):
        warnings.append(message)
        warn_line(message)

    frames = frame_range(frame_spec) if frame_spec is not None else None
    cfg = load_config(config_file, sets)
    doc = check_recording(open_recording(recording, reader, reader_options(reader_opts)), warn=warn,
                          frames_settings=cfg["frames"], frames=frames)
    doc["warnings"] = warnings
    if as_json:
        click.echo(json.dumps(doc, indent=2))
    else:
        up, poses = doc["up"], doc["poses"]
        x, y, z = up["direction"]
        m_cfg = cfg["modeling"]
        depth = (f"{doc['depth_range'][0]:g}-{doc['depth_range'][1]:g} m (the recording's range)"
                 if doc["depth_range"] else f"{m_cfg['min_depth']:g}-{m_cfg['max_depth']:g} m (the settings' "
                                            "modeling.min_depth and max_depth)")
        click.echo(f"recording    {doc['recording']}  ({doc['reader']}, {plural(doc['frames'], 'frame')})")
        click.echo(f"camera       {camera_text(doc['camera'])}")
        if doc["still_frames"] is not None:
            click.echo(f"still        {still_text(doc['still_frames'])}")
        click.echo(f"depth        {depth}")
        click.echo(f"up           {up['how']}: map +z = the recording's ({x:.3f}, {y:.3f}, {z:.3f}), "
                   f"{up['tilt_deg']:.1f} deg from its +z")
        click.echo(f"floor        " + (f"z = {doc['floor_z']:.3f} m in the map frame" if doc["floor_z"] is not None
                                       else "not in view of the sampled frames"))
        if poses is not None:
            others = ", ".join(f"{k} {v:.0%}" for k, v in poses["agree"].items() if k != "as given")
            click.echo(f"poses        {poses['agree']['as given']:.0%} of depth readings within "
                       f"{poses['tolerance_m'] * 100:.0f} cm of the next frame's as read; read {others}")
    verdict = f"{plural(len(warnings), 'warning')} (above)" if warnings else "ready to ingest"
    click.echo(f"{recording}: {verdict}", err=as_json)
