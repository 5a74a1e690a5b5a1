"""The one way a generated block goes into a Markdown page: between its two marker lines."""

from __future__ import annotations

from keras_rl.errors import ConfigError


def seed_span(seeds: list[int]) -> str:
    """``0-29`` for a run of consecutive seeds, else the list."""
    if seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"{seeds[0]}-{seeds[-1]}"
    return ",".join(str(s) for s in seeds)


def replace_block(content: str, begin: str, end: str, text: str) -> str:
    """``content`` with what lies between the ``begin`` and ``end`` markers replaced by ``text``;
    a ConfigError if the page lacks either marker."""
    if begin not in content or end not in content:
        raise ConfigError(f"the page has no {begin} ... {end} markers to replace")
    head, rest = content.split(begin, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{begin}\n{text}\n{end}{tail}"
