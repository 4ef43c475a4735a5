"""Help pages without Typer's type labels: no `<bool>` on flags, no `<str>`, no `{file}`.

Typer labels every parameter with its Python type. Commands and groups built with
`TidyCommand` and `TidyGroup` show instead the allowed values of a choice (`[lru|least_hit]`),
a word for other values (`TEXT`, `INTEGER`, `PATH`, or the option's `metavar`), nothing for
flags, and arguments by their upper-case name.
"""

from __future__ import annotations

from typing import Any

from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

_WORDS = {"str": "TEXT", "int": "INTEGER", "float": "FLOAT", "bool": "BOOLEAN"}


class _Option(TyperOption):
    def display_type_rich(self, ctx: Any) -> str | None:
        if self.metavar is not None or self.is_flag:
            return self.metavar or None
        label = str(super().display_type_rich(ctx) or "").strip("<>").removesuffix("...")
        label = label.removeprefix("list[").removesuffix("]").removesuffix(" range")
        if "|" in label:
            return f"[{label}]"
        return _WORDS.get(label, label.upper())


class _Argument(TyperArgument):
    @property
    def display_name_raw(self) -> str:
        return (self.metavar or self.name or "").upper()

    def display_type_rich(self, ctx: Any) -> str | None:
        return None

    def _usage_display_name(self) -> str:
        name = self.display_name_raw + ("..." if self.nargs != 1 else "")
        return name if self.required else f"[{name}]"


def _tidy(params: list[Any]) -> list[Any]:
    for param in params:
        if type(param) is TyperOption:
            param.__class__ = _Option
        elif type(param) is TyperArgument:
            param.__class__ = _Argument
    return params


class TidyCommand(TyperCommand):
    """A command whose help shows values, not Python types."""

    def get_params(self, ctx: Any) -> list[Any]:
        """The parameters, help option included, with tidy help labels."""
        return _tidy(super().get_params(ctx))


class TidyGroup(TyperGroup):
    """A command group whose help shows values, not Python types."""

    def get_params(self, ctx: Any) -> list[Any]:
        """The parameters, help and completion options included, with tidy help labels."""
        return _tidy(super().get_params(ctx))
