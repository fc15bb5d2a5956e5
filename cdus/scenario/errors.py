"""What a person sees when a scenario cannot run: one error with every problem in it."""

from __future__ import annotations

from typing import Iterable


class ConfigError(Exception):
    """A config that cannot be run. ``str(e)`` is one ``<file>: <field>: <message>`` line per problem."""

    def __init__(self, source: str, problems: Iterable[tuple[str, str]]):
        self.source = source
        self.problems: list[tuple[str, str]] = list(problems)
        super().__init__("\n".join(f"{source}: {f}: {m}" for f, m in self.problems))

    def __reduce__(self):  # picklable across processes
        return (type(self), (self.source, self.problems))
