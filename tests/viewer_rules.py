"""What Foxglove and Lichtblick accept, written from Lichtblick's own source (1.28,
lichtblick-suite/lichtblick): the JSON schemas its parser reads (packages/mcap-support/src/
parseJsonSchema.ts), the layouts its import accepts (packages/suite-base/src/util/layout.ts,
validateLayoutData) and the rate above which it warns of high frequency topics
(packages/suite-base/src/players/utils/constants.ts)."""

FREQUENCY_LIMIT_HZ = 60.0
LICHTBLICK_PANELS = {"3D", "Plot", "RosOut"}  # the panel types our layout uses (panels/index.ts)


def json_schema_errors(schema: object, where: str = "") -> list[str]:
    """Why Lichtblick's parseJsonSchema would refuse ``schema`` ([] when it parses it)."""
    if not isinstance(schema, dict) or schema.get("type") != "object":
        return [f'{where or "root"}: expected "type": "object"']
    errors = []
    for name, field in (schema.get("properties") or {}).items():
        path = f"{where}.{name}" if where else name
        if not isinstance(field, dict):
            errors.append(f"{path}: not a schema")
        elif isinstance(field.get("oneOf"), list):
            if not all(isinstance(a, dict) and isinstance(a.get("const"), (int, float)) for a in field["oneOf"]):
                errors.append(f"{path}: oneOf alternatives must have number values")
        elif field.get("type") in ("boolean", "number", "integer"):
            pass
        elif field.get("type") == "string":
            if field.get("contentEncoding") not in (None, "base64"):
                errors.append(f"{path}: unsupported contentEncoding")
        elif field.get("type") == "object":
            errors += json_schema_errors(field, path)
        elif field.get("type") == "array":
            items = field.get("items") if isinstance(field.get("items"), dict) else {}
            if items.get("type") in ("boolean", "number", "integer"):
                pass
            elif items.get("type") == "string" and items.get("contentEncoding") is None:
                pass
            elif items.get("type") == "object":
                errors += json_schema_errors(items, path)
            else:
                errors.append(f"{path}: unsupported array item type {items.get('type')!r}")
        else:
            errors.append(f"{path}: unsupported type {field.get('type')!r}")
    return errors


def lichtblick_layout_errors(data: object) -> list[str]:
    """Why Lichtblick's layout import would refuse ``data``, and leaves of its tree without a config
    or of a panel type our layout does not mean to use ([] when it accepts it)."""
    if not isinstance(data, dict):
        return ["expected an object"]
    errors = [
        f"missing or invalid {f!r}" for f in ("configById", "globalVariables") if not isinstance(data.get(f), dict)
    ]
    playback = data.get("playbackConfig")
    if not (isinstance(playback, dict) and isinstance(playback.get("speed"), (int, float))):
        errors.append("missing or invalid 'playbackConfig'")
    if "userNodes" in data and not isinstance(data["userNodes"], dict):
        errors.append("invalid 'userNodes'")
    layout = data.get("layout")
    if layout is not None and not isinstance(layout, (str, dict)):
        errors.append("invalid 'layout'")
    leaves, stack = [], [layout]
    while stack:
        node = stack.pop()
        if isinstance(node, str):
            leaves.append(node)
        elif isinstance(node, dict):
            stack += [node.get("first"), node.get("second")]
    configs = data.get("configById") if isinstance(data.get("configById"), dict) else {}
    errors += [f"panel {leaf!r} has no config" for leaf in leaves if leaf not in configs]
    errors += [f"panel {leaf!r}: unknown type" for leaf in leaves if leaf.split("!")[0] not in LICHTBLICK_PANELS]
    return errors
