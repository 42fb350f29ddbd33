"""The settings tables of docs/parameters.md, made from the schemas.

Every setting of the study's configuration (``workflow/schemas/config.schema.yaml``
without the numerics checks, with the simulator's sections from
``sim/config.schema.yaml`` that it refers to, and ``analysis/params.schema.yaml``
for the ``analysis`` section) as one row: its key, default, allowed values and
the schema's description. The schemas are the one source of the settings; this
script writes their tables between the marker lines of the page::

    python -m workflow.tools settings_table --write docs/parameters.md
    python -m workflow.tools settings_table --check docs/parameters.md   # exit 1 if out of date

(``tests/test_config_schema.py`` runs the check.)
"""

import json
import sys
from pathlib import Path

import yaml

from ._cli import ToolParser, existing_file, refuse

REPO = Path(__file__).resolve().parents[2]
SCHEMAS = REPO / "workflow" / "schemas"
ANALYSIS_SCHEMA = REPO / "analysis" / "params.schema.yaml"
BEGIN = "<!-- settings tables: made by workflow/tools/settings_table.py from the schemas; do not edit -->"
END = "<!-- end of the settings tables -->"
# Top-level keys of config.schema.yaml that get no rows here: the analysis has
# its own schema (its own table), the numerics checks have theirs (docs/numerics.md).
OWN_TABLE = ("analysis", "numerics")


def _value(v) -> str:
    return "null" if v is None else json.dumps(v) if isinstance(v, (list, dict, str, bool)) else f"{v:g}"


def allowed(spec: dict) -> str:
    """What a setting may be, from its type, bounds and enum."""
    types = spec.get("type", [])
    types = [types] if isinstance(types, str) else list(types)
    if "enum" in spec:
        return " or ".join(f"`{_value(v)}`" for v in spec["enum"])
    if "array" in types:
        items = spec.get("items", {})
        size = ""
        lo, hi = spec.get("minItems"), spec.get("maxItems")
        if lo is not None and lo == hi:
            size = f", {lo} items"
        elif lo is not None or hi is not None:
            size = "".join([f", at least {lo}" if lo else "", f", at most {hi}" if hi is not None else ""])
        inner = allowed(items) if items else "any"
        return f"list of ({inner}){size}" + (", no repeats" if spec.get("uniqueItems") else "")
    parts = []
    kind = [t for t in types if t != "null"]
    if kind:
        parts.append(" or ".join(kind))
    lo = ("≥", spec["minimum"]) if "minimum" in spec else (">", spec["exclusiveMinimum"]) \
        if "exclusiveMinimum" in spec else None
    hi = ("≤", spec["maximum"]) if "maximum" in spec else ("<", spec["exclusiveMaximum"]) \
        if "exclusiveMaximum" in spec else None
    parts += [f"{bound[0]} {_value(bound[1])}" for bound in (lo, hi) if bound is not None]
    text = ", ".join(parts)
    return text + (" or null" if "null" in types else "")


def rows(properties: dict, prefix: str = "", defs: dict | None = None) -> list[str]:
    """Table rows of ``properties``, depth first; objects with properties of their own
    are opened, references to ``$defs`` followed: local ones (``#/$defs/...``) in
    ``defs``, those to another file (``../../sim/config.schema.yaml#/$defs/...``)
    in that file, relative to workflow/schemas."""
    out = []
    for key, spec in properties.items():
        name = f"{prefix}{key}"
        if "$ref" in spec and "#/$defs/" in spec["$ref"]:
            file, _, target = spec["$ref"].partition("#/$defs/")
            found = yaml.safe_load((SCHEMAS / file).read_text())["$defs"] if file else defs
            spec = {**found[target], **{k: v for k, v in spec.items() if k != "$ref"}}
        if spec.get("type") == "object" and "properties" in spec:
            out += rows(spec["properties"], f"{name}.", defs)
            continue
        description = " ".join(str(spec.get("description", "")).split()).replace("|", "\\|")
        default = f"`{_value(spec['default'])}`" if "default" in spec else "required"
        out.append(f"| `{name}` | {default} | {allowed(spec)} | {description} |")
    return out


def tables() -> str:
    """The Markdown of both tables, between the marker lines."""
    config = yaml.safe_load((SCHEMAS / "config.schema.yaml").read_text())
    analysis = yaml.safe_load(ANALYSIS_SCHEMA.read_text())["$defs"]["analysis"]
    head = ["| setting | default | allowed | meaning |", "|---|---|---|---|"]
    study = {k: v for k, v in config["properties"].items() if k not in OWN_TABLE}
    return "\n".join([BEGIN, "", "### The simulation and the workflow (`workflow/schemas/config.schema.yaml`, "
                      "the simulator's sections from `sim/config.schema.yaml`)", "",
                      *head, *rows(study, "", config.get("$defs", {})), "",
                      "### The analysis (`analysis`, `analysis/params.schema.yaml`)", "",
                      *head, *rows(analysis["properties"], "analysis."), "", END])


def replaced(page: str, name: str) -> str:
    """``page`` (the text of the file `name`) with the text between the marker lines replaced by :func:`tables`."""
    if BEGIN not in page or END not in page:
        refuse(f"{name}: no marker lines {BEGIN!r} ... {END!r}; allowed is a page that has them")
    before, rest = page.split(BEGIN, 1)
    return before + tables() + rest.split(END, 1)[1]


def main(argv=None) -> int:
    ap = ToolParser(description=__doc__.splitlines()[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", metavar="PAGE", type=existing_file, help="rewrite the tables of PAGE")
    mode.add_argument("--check", metavar="PAGE", type=existing_file,
                      help="exit 1 if the tables of PAGE differ from the schemas")
    args = ap.parse_args(argv)
    path = args.write or args.check
    page = path.read_text()
    new = replaced(page, str(path))
    if args.write:
        path.write_text(new)
        return 0
    if new != page:
        print(f"{path}: the settings tables differ from the schemas; run "
              f"python -m workflow.tools settings_table --write {path}", file=sys.stderr)
        return 1
    return 0
