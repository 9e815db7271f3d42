"""The text form of an evaluation (``ltc evaluate``'s table and summary line). Returns lines; the CLI
prints them."""

from __future__ import annotations


def fmt_value(v, spec: str = ".3f") -> str:
    """A ratio or mean as text; ``n/a`` for None (0/0, or a mean over no true positive)."""
    return "n/a" if v is None else format(v, spec)


_HEAD = (f"{'':<14}{'TP':>5}{'FP':>5}{'FN':>5} {'precision':>9} {'recall':>7} {'recall*':>7} {'F1':>6} "
         f"{'XY IoU':>7} {'VIoU':>6} {'pos err':>8} {'dup':>4} {'ghost':>5}")


def _line(name: str, r: dict) -> str:
    # "-": not computed for this row (recall* per class; duplicates and ghosts at IoU thresholds).
    dup, ghost = r.get("duplicates", "-"), r.get("ghosts", "-")
    seen = fmt_value(r["recall_seen"]) if "recall_seen" in r else "-"
    return (f"{name:<14}{r['tp']:>5}{r['fp']:>5}{r['fn']:>5} {fmt_value(r['precision']):>9} "
            f"{fmt_value(r['recall']):>7} {seen:>7} {fmt_value(r['f1']):>6} "
            f"{fmt_value(r['mean_xy_iou']):>7} {fmt_value(r['mean_viou']):>6} "
            f"{fmt_value(r['mean_position_error']):>8} {dup:>4} {ghost:>5}")


def evaluation_table(res: dict) -> list[str]:
    """Per-class rows and "all" at any overlap, then "all" at each XY IoU threshold, then notes on
    the definitions and the multi-lap figures."""
    lines = [_HEAD]
    for name, r in sorted(res["per_class"].items()):
        lines.append(_line(name[:13], r))
    lines.append(_line("all", res))
    for t, r in res.get("at_iou", {}).items():
        lines.append(_line(f"XY IoU > {t}", r))
    lines.append("TP: one-to-one, same class, any footprint overlap; rows 'XY IoU > t': all classes, "
                 "a TP needs footprint (XY) IoU > t")
    lines.append("recall*: over the objects the robot saw; n/a: 0/0 or not known; position error in metres")
    lines.append(f"ghost: unmatched map object where an object stood in any of {res.get('earlier_laps', 0)} "
                 f"earlier lap(s); dup: second map object on a matched object")
    d = res.get("deleted_while_present")
    if d is not None:
        lines.append(f"maintenance deleted a map object on {d['count']} of the {d['present']} objects "
                     f"present in this lap ({fmt_value(d['share'], '.1%')}); "
                     f"{len(d.get('lost_gt_ids', []))} of them not in the map now; "
                     f"{len(d.get('duplicates_removed', []))} second box(es) removed from objects still mapped")
    return lines


def evaluation_summary(res: dict) -> str:
    """One line: the any-overlap figures, the XY IoU > 0.25 ones, duplicates, ghosts, deletions."""
    text = (f"precision {fmt_value(res['precision'])}, recall {fmt_value(res['recall'])} "
            f"(seen {fmt_value(res['recall_seen'])}), F1 {fmt_value(res['f1'])}, "
            f"XY IoU {fmt_value(res['mean_xy_iou'])}")
    strict = res.get("at_iou", {}).get("0.25")
    if strict is not None:
        text += (f"; at XY IoU > 0.25: precision {fmt_value(strict['precision'])}, "
                 f"recall {fmt_value(strict['recall'])}")
    text += f"; {res['duplicates']} duplicates, {res['ghosts']} ghosts"
    d = res.get("deleted_while_present")
    if d is not None:
        text += f", {d['count']} present objects deleted by maintenance"
    return text
