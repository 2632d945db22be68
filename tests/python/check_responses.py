"""Validates recorded HTTP answers against openapi.yaml.

stdin: JSON list of {"path", "method", "status", "body"}; argv[1]: the spec.
Each body is validated (JSON Schema 2020-12, as OpenAPI 3.1 uses) against the
schema the spec gives for that path, method and status. Prints "ok N".
"""
import json
import sys

import yaml
from jsonschema import Draft202012Validator

spec = yaml.safe_load(open(sys.argv[1]))
samples = json.load(sys.stdin)


def resolve(node):
    while isinstance(node, dict) and "$ref" in node and len(node) == 1:
        ref = node["$ref"]
        assert ref.startswith("#/"), ref
        target = spec
        for part in ref[2:].split("/"):
            target = target[part]
        node = target
    return node


failures = []
for s in samples:
    operation = spec["paths"][s["path"]][s["method"].lower()]
    response = operation["responses"].get(str(s["status"]))
    if response is None:
        failures.append(f'{s["method"]} {s["path"]}: status {s["status"]} not in the spec')
        continue
    response = resolve(response)
    schema = response["content"]["application/json"]["schema"]
    # Refs inside resolve against the whole document.
    wrapped = dict(schema)
    wrapped["components"] = spec["components"]
    errors = sorted(Draft202012Validator(wrapped).iter_errors(s["body"]), key=str)
    for e in errors[:3]:
        failures.append(f'{s["method"]} {s["path"]} {s["status"]}: {e.message} at {list(e.absolute_path)}')
if failures:
    print("\n".join(failures), file=sys.stderr)
    sys.exit(1)
print(f"ok {len(samples)}")
