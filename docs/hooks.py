"""MkDocs hooks: pages that must stay true of the repository are made from it at build time.

- The home page (docs/index.md, a placeholder) is README.md, its links made relative to docs/
  (the README links ``docs/tutorials/x.md``, the site ``tutorials/x.md``).
- The mission file reference gets the table of every setting of the schema
  (``autonomy.config.Mission``): key, type, default, bounds and description, where the page
  says ``<!-- mission schema -->``.
"""

from __future__ import annotations

import re
import sys
import typing
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCHEMA_MARKER = "<!-- mission schema -->"


def on_page_markdown(markdown: str, page, config, files) -> str:
    if page.file.src_uri == "index.md":
        return re.sub(r"\]\(docs/", "](", (ROOT / "README.md").read_text(encoding="utf-8"))
    if SCHEMA_MARKER in markdown:
        return markdown.replace(SCHEMA_MARKER, mission_schema_tables())
    return markdown


def mission_schema_tables() -> str:
    """One Markdown table per top-level section of the mission schema."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))  # this checkout's code, not another install's
    from autonomy.config import Mission

    head = "| key | type | default | bounds | what it is |\n| --- | --- | --- | --- | --- |\n"
    top, sections = [], []
    for name, field in Mission.model_fields.items():
        models = _models(field.annotation)
        if models:
            body = "".join(_row(*r) for r in _rows_of(name, field, models))
            sections.append(f"### `{name}`\n\n{head}{body}")
        else:
            top.append(_row(name, *_describe(field)))
    return "### Top level\n\n" + head + "".join(top) + "\n" + "\n".join(sections)


def _rows_of(key: str, field, models: list) -> typing.Iterator[tuple]:
    if len(models) > 1:  # a discriminated union, e.g. world kinds
        kinds = [str(m.model_fields["kind"].default) if "kind" in m.model_fields else m.__name__
                 for m in models]
        yield key, "one of: " + ", ".join(kinds), "", "", field.description or ""
        for model, kind in zip(models, kinds, strict=True):
            yield from _rows(model, f"{key} (kind {kind}).")
        return
    if field.description:
        yield key, "section", "", "", field.description
    yield from _rows(models[0], key + ".")


def _rows(model, prefix: str) -> typing.Iterator[tuple]:
    for name, field in model.model_fields.items():
        models = _models(field.annotation)
        if models:
            yield from _rows_of(prefix + name, field, models)
        else:
            yield (prefix + name, *_describe(field))


def _describe(field) -> tuple[str, str, str, str]:
    from pydantic_core import PydanticUndefined

    if field.default is not PydanticUndefined:
        default = f"`{field.default!r}`"
    else:
        default = "required" if field.default_factory is None else "derived"
    bounds = []
    for meta in field.metadata:
        for attr, sign in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<")):
            value = getattr(meta, attr, None)
            if value is not None:
                bounds.append(f"{sign} {value:,}" if isinstance(value, (int, float))
                              else f"{sign} {value}")
    return _type(field.annotation), default, ", ".join(bounds), field.description or ""


def _models(annotation) -> list:
    from pydantic import BaseModel

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models(arg)]


def _type(annotation) -> str:
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Annotated:
        return _type(args[0])
    if origin is typing.Literal:
        return " or ".join(f"`{a}`" for a in args)
    if args and (origin is typing.Union or type(annotation).__name__ == "UnionType"):
        return " or ".join(_type(a) for a in args)
    if origin in (list, tuple, dict):
        inner = ", ".join(_type(a) for a in args if a is not Ellipsis)
        return f"{origin.__name__}[{inner}]"
    if annotation is type(None):
        return "none"
    return getattr(annotation, "__name__", str(annotation))


def _row(*cells: str) -> str:
    return "| " + " | ".join(str(c).replace("|", "\\|").replace("\n", " ") for c in cells) + " |\n"
