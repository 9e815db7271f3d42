"""Small helpers for the words ltc writes for people (command summaries, removal reasons)."""


def plural(n: int, word: str) -> str:
    """ "1 frame", "2 frames", "0 frames"; "2 classes", "2 boxes"."""
    if n == 1:
        return f"{n} {word}"
    return f"{n} {word}{'es' if word.endswith(('s', 'x', 'sh', 'ch')) else 's'}"
