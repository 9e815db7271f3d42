"""Skipped frames are listed ten to a kind of reason, then counted (ltc_cli.text.SkippedFrames)."""

from ltc_cli.errors import FrameError
from ltc_cli.text import SkippedFrames, reason_key, skip_reason, skipped_breakdown


def test_reasons_that_differ_only_in_names_and_numbers_are_one_kind():
    assert skip_reason("cannot read image (OSError: image file is truncated (13 bytes not processed))") \
        == "cannot read image"
    assert reason_key("topic /cam/depth: no message stamped 1305031229.926 s") \
        == reason_key("topic /cam/depth: no message stamped 1305031230.130 s") \
        == "topic /cam/depth: no message stamped N s"
    assert reason_key("frame '000012' has no pose line") == "frame '…' has no pose line"
    assert reason_key("image file is missing") == "image file is missing"
    # A parenthesis that is part of the reason stays, numbers aside.
    assert skip_reason("depth image must have one channel, got shape (480, 640, 3)") \
        == "depth image must have one channel, got shape (480, 640, 3)"
    assert reason_key(skip_reason("depth image must have one channel, got shape (480, 640, 3)")) \
        == "depth image must have one channel, got shape (N, N, N)"
    assert skip_reason("not valid JSON (Expecting value: line 1 column 1 (char 0))") == "not valid JSON"


def test_a_kind_is_listed_ten_times_then_counted_and_named_by_its_kind_when_reasons_differ():
    lines = []
    skips = SkippedFrames(lines.append)
    for i in range(12):
        skips.skip(f"{i:03d}", FrameError(f"topic /cam/depth: no message stamped {100 + i}.5 s", "a.bag"))
    for i in (3, 7):
        skips.skip(f"p{i}", FrameError(f"frame '{i:06d}' has no pose line", "poses.txt"))
    for i in range(2):
        skips.skip(f"m{i}", FrameError("image file is missing", f"depth/{i}.png"))
    assert len(lines) == 11 + 2 + 2
    assert lines[0] == "skipped frame 000: a.bag: topic /cam/depth: no message stamped 100.5 s"
    assert lines[9] == "skipped frame 009: a.bag: topic /cam/depth: no message stamped 109.5 s"
    assert lines[10] == ("skipped frame 010: a.bag: topic /cam/depth: no message stamped 110.5 s; further frames "
                         'skipped for "topic /cam/depth: no message stamped N s" are counted in the summary, '
                         "not listed")
    assert lines[11] == "skipped frame p3: poses.txt: frame '000003' has no pose line"
    assert lines[14] == "skipped frame m1: depth/1.png: image file is missing"
    # One reason said alike every time keeps its words; reasons that differed go by their kind.
    assert skips.counts == {"topic /cam/depth: no message stamped N s": 12, "frame '…' has no pose line": 2,
                            "image file is missing": 2}
    assert skipped_breakdown(skips.counts) == ("12 topic /cam/depth: no message stamped N s, "
                                               "2 frame '…' has no pose line, 2 image file is missing")


def test_one_reason_of_its_kind_keeps_its_own_words():
    skips = SkippedFrames(lambda line: None)
    for i in range(3):
        skips.skip(str(i), FrameError("colour image is 640x480, the camera is 320x240", f"rgb/{i}.png"))
    assert skips.counts == {"colour image is 640x480, the camera is 320x240": 3}
