"""test_spec.py - PROTOCOL.md's tables agree with messages.json (ids, payload fields, status codes, keys)."""
import json
import os
import re

from conftest import PROTOCOL_DIR

with open(os.path.join(PROTOCOL_DIR, "messages.json")) as f:
    SPEC = json.load(f)
with open(os.path.join(PROTOCOL_DIR, "PROTOCOL.md")) as f:
    DOC = f.read()


def section(title):
    """The text under '## title' (up to the next '## ' heading)."""
    start = DOC.index("\n## " + title + "\n")
    end = DOC.find("\n## ", start + 1)
    return DOC[start:end if end > 0 else len(DOC)]


def table_rows(first_cell_pattern, text):
    rows = []
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("|") and re.fullmatch(first_cell_pattern, cells[0]):
            rows.append(cells)
    return rows


def doc_fields(cell):
    """'target i32[6], duration_ms u16' -> [['target', 'i32', 6], ['duration_ms', 'u16']]"""
    if cell == "—":
        return []
    out = []
    for part in cell.split(", "):
        m = re.match(r"(\w+) ([ui]\d+)(?:\[(\d+)\])?", part)
        out.append([m.group(1), m.group(2)] + ([int(m.group(3))] if m.group(3) else []))
    return out


def resolved(fields):
    """messages.json's fields with a per-joint count ("joints") replaced by the joint count, as PROTOCOL.md writes it."""
    return [f[:2] + [SPEC["joints"] if f[2] == "joints" else f[2]] if len(f) > 2 else f for f in fields]


def test_message_table():
    rows = table_rows(r"0x[0-9A-F]{2}", section("Messages"))
    assert [(int(r[0], 16), r[1]) for r in rows] == [(m["id"], m["name"]) for m in SPEC["messages"]]
    for r, m in zip(rows, SPEC["messages"]):
        if m.get("firmware_only"):
            assert doc_fields(r[2].replace("(firmware to host only) ", "")) == resolved(m["payload"])
        else:
            assert doc_fields(r[2]) == resolved(m["request"]), m["name"]
            assert doc_fields(r[3]) == resolved(m["response"][1:]), m["name"]


def test_status_table():
    rows = table_rows(r"\d+", section("Status codes"))
    assert [(int(r[0]), r[1]) for r in rows] == [(c, n) for c, n, _ in SPEC["status"]]


def test_state_table():
    rows = table_rows(r"\d+", section("States"))
    assert [(int(r[0]), r[1]) for r in rows] == [tuple(s) for s in SPEC["states"]]


def test_config_key_tables():
    rows = table_rows(r"\d+", section("Messages").split("### Configuration keys")[1])
    assert [(int(r[0]), r[1], int(r[4])) for r in rows] == [(k["key"], k["name"], k["default"])
                                                            for k in SPEC["config_keys"]]


def test_payload_length_line():
    from rbx1proto import messages
    for t in messages.MsgType:
        if t != messages.MsgType.NAK:
            assert f"{t.name} {messages.request_len(t)}/{messages.response_len(t)}" in DOC.replace("\n", " ")
