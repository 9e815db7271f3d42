"""Small helpers for the words ltc writes for people (command summaries, removal reasons)."""

import re


def plural(n: int, word: str) -> str:
    """ "1 frame", "2 frames", "0 frames"; "2 classes", "2 boxes"."""
    if n == 1:
        return f"{n} {word}"
    return f"{n} {word}{'es' if word.endswith(('s', 'x', 'sh', 'ch')) else 's'}"


LISTED_PER_REASON = 10

_QUOTED = re.compile(r"'[^']*'|\"[^\"]*\"")
_NUMBER = re.compile(r"\d+(?:\.\d+)?")


def skip_reason(message: str) -> str:
    """What a skipped frame's error says, without the underlying error's text that closes it
    ("cannot read image (OSError: ... 'rgb/1.jpg')" -> "cannot read image"). A closing
    parenthesis that holds no such "Name: text" stays: "... got shape (480, 640, 3)"."""
    head, sep, rest = message.partition(" (")
    return head if sep and rest.endswith(")") and ":" in rest else message


def reason_key(reason: str) -> str:
    """The kind of a :func:`skip_reason`, its names and numbers left out: "frame '000012' has no
    pose line" and "frame '000013' has no pose line" are one kind, "frame '…' has no pose line"."""
    return _NUMBER.sub("N", _QUOTED.sub("'…'", reason))


class SkippedFrames:
    """Skipped frames counted by reason, and warned about: the first ``listed`` of each kind of
    reason (:func:`reason_key`) one line each, then one line saying that the rest are only counted.
    A recording copied in part (its index lists 232 frames, 40 images arrived) otherwise buries the
    warnings that matter under 192 lines of "image file is missing"."""

    def __init__(self, warn, listed: int = LISTED_PER_REASON):
        self.warn = warn
        self.listed = listed
        self.kinds: dict[str, int] = {}  # reason_key -> frames
        self.said: dict[str, str] = {}  # reason_key -> its reason, or the key when reasons differed

    def skip(self, key: str, exc) -> None:
        """Count frame ``key``, skipped for ``exc`` (an LtcError), and warn as the class says."""
        reason = skip_reason(exc.message)
        kind = reason_key(reason)
        if self.said.setdefault(kind, reason) != reason:
            self.said[kind] = kind
        n = self.kinds[kind] = self.kinds.get(kind, 0) + 1
        if n <= self.listed:  # the (listed + 1)th says that it is the last line of its kind
            self.warn(f"skipped frame {key}: {exc}")
        elif n == self.listed + 1:
            self.warn(f"skipped frame {key}: {exc}; further frames skipped for \"{kind}\" are counted in "
                      "the summary, not listed")

    @property
    def counts(self) -> dict[str, int]:
        """{reason: frames}: each kind under its one reason, or under the kind where they differed."""
        return {self.said[kind]: n for kind, n in self.kinds.items()}


def skipped_breakdown(counts: dict[str, int]) -> str:
    """ "192 image file is missing, 3 cannot read image" (most frequent first); "" for none."""
    return ", ".join(f"{n} {reason}" for reason, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))
