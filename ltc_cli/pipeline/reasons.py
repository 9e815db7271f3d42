"""The event log's words for why maintenance removed an object: one line each, read by people
(`ltc query --removed`, `ltc changes`) and starting with a fixed word that tools match."""

from __future__ import annotations

import numpy as np

from ltc_cli.text import plural


def absent_detail(in_session: int, since_detection: int, seen_through: int | None = None) -> str:
    """The event log's reason for a removal by the absence rule (starts "other: clearly"); with
    ``seen_through``, how many of the views since its last detection saw through its box."""
    through = "" if seen_through is None else f", its place seen empty in {int(seen_through)}"
    return (f"other: clearly visible in {int(in_session)} frames of this session ({int(since_detection)} since its "
            f"last detection{through}), detected in none")


def unconfirmed_detail(n_det: int, n_clear: int, min_detections: int, min_share: float | None,
                       views: int = 0, min_views: int | None = None) -> str:
    """The event log's reason for a removal as unconfirmed (starts "unconfirmed:")."""
    return (f"unconfirmed: {plural(int(n_det), 'detection')} in {int(n_clear)} clear views in the session that "
            f"created it (needs {min_detections}" + (f" and {min_share:.0%} of its clear views" if min_share else "")
            + (f"; detected from {plural(int(views), 'distinct view')}, needs {min_views})" if min_views else ")"))


def other_leads_detail(scores: np.ndarray, classes: list[str], n_nondet: int, n_det: int) -> str:
    """The event log's reason for a removal by eq. 4 (starts "other")."""
    top = int(np.asarray(scores)[:-1].argmax())
    return (f"other {scores[-1]:.3f} > {classes[top]} {scores[top]:.3f} after "
            f"{plural(int(n_nondet), 'non-detection')} and {plural(int(n_det), 'detection')}")


def removed_by_misses(detail: str) -> bool:
    """True for the reason :func:`other_leads_detail` writes (eq. 4: "other 0.540 > ..."), not the
    absence rule's ("other: clearly ...")."""
    return detail.startswith("other ")


def returned_detail(new_id: int, n_det: int) -> str:
    """The event log's reason for an object's return (starts "returned:")."""
    return (f"returned: non-detections removed it in this session, and object {int(new_id)}, "
            f"{plural(int(n_det), 'detection')} of its class at its place, is it")


def reidentified_detail(new_id: int, n_det: int) -> str:
    """The event log's reason for re-identifying an object of an earlier session (starts
    "re-identified:")."""
    return (f"re-identified: not detected at its box in this session, and object {int(new_id)}, "
            f"{plural(int(n_det), 'detection')} of its class just beside it, is it")


def joined_detail(new_id: int, n_det: int, iou: float) -> str:
    """The event log's reason for an earlier session's object taking a new one of its class that
    overlaps it (starts "joined:")."""
    return (f"joined: object {int(new_id)} of this session, {plural(int(n_det), 'detection')} of its class, "
            f"overlaps its box (XY IoU {iou:.2f}) and is it")


def picture_detail(n_flat: int, n_det: int) -> str:
    """The event log's reason for a removal as a picture on a wall (starts "picture:")."""
    return (f"picture: {plural(int(n_flat), 'detection')} of it lay flat on the wall around "
            f"{'it' if int(n_flat) == 1 else 'them'}, beside {plural(int(n_det), 'other')}")
