"""The problems found while loading one file (:class:`Report`): every error and warning,
located, raised together as one :class:`~cellrunner.errors.InputError`."""

from __future__ import annotations

from dataclasses import dataclass, field

from cellrunner.errors import Diagnostic, InputError
from cellrunner.model.diagnose import dotted
from cellrunner.model.source import PathKey, Source


@dataclass
class Report:
    """Errors and warnings collected while loading one file."""

    source: Source
    errors: list[Diagnostic] = field(default_factory=list)
    warnings: list[Diagnostic] = field(default_factory=list)

    def error(self, path: PathKey, message: str, *, at_key: bool = False) -> None:
        where = dotted(path)
        self.errors.append(
            self.source.diagnostic(path, f"{where}: {message}" if where else message, at_key=at_key)
        )

    def warn(self, path: PathKey, message: str) -> None:
        self.warnings.append(
            self.source.diagnostic(path, f"{dotted(path)}: {message}", severity="warning")
        )

    def raise_if_errors(self) -> None:
        if self.errors:
            raise InputError(sorted(self.errors, key=lambda d: (d.line, d.col)))
