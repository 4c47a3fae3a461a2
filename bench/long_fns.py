#!/usr/bin/env python3
"""Lists Rust functions longer than a limit (issue #22: "no function longer than about 150
lines anywhere without a reason written at its top").

Usage: python3 bench/long_fns.py [--limit 150] [DIR ...]   (default: crates src)

A function is counted from its `fn` line to its closing brace. It passes when a comment
in the ten lines above the `fn` line (its doc comment or attributes) or in the first five
lines of its body says why it is long: the word "long" or "length" together with
"because", "reason" or ":" . The exit status is the number of functions without a
reason (0: every long function says why), at most 100.
"""

import re
import sys
from pathlib import Path

FN = re.compile(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+\"[^\"]*\"\s+)?fn\s+(\w+)")


def strip(line, state):
    """The line without strings, chars and comments; state carries block comments and
    multi-line strings across lines."""
    out = []
    i = 0
    n = len(line)
    while i < n:
        c = line[i]
        if state["block"]:
            if line.startswith("*/", i):
                state["block"] -= 1
                i += 2
            elif line.startswith("/*", i):
                state["block"] += 1
                i += 2
            else:
                i += 1
            continue
        if state["str"]:
            if c == "\\" and not state["raw"]:
                i += 2
                continue
            if c == '"' and line.startswith('"' + "#" * state["hashes"], i):
                state["str"] = False
                i += 1 + state["hashes"]
            else:
                i += 1
            continue
        if line.startswith("//", i):
            break
        if line.startswith("/*", i):
            state["block"] = 1
            i += 2
            continue
        m = re.match(r'(b?r)(#*)"', line[i:])
        if m and (i == 0 or not (line[i - 1].isalnum() or line[i - 1] == "_")):
            state.update(str=True, raw=True, hashes=len(m.group(2)))
            i += len(m.group(0))
            continue
        if c == '"':
            state.update(str=True, raw=False, hashes=0)
            i += 1
            continue
        if c == "'":
            # A char literal ('x', '\n', '\u{..}') or a lifetime ('a).
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", line[i:])
            if m:
                i += len(m.group(0))
                continue
        out.append(c)
        i += 1
    return "".join(out)


def reason(lines, start, end):
    """Whether a comment near the function's top says why it is long."""
    window = lines[max(0, start - 10) : start] + lines[start : min(end, start + 6)]
    for l in window:
        s = l.strip()
        if not (s.startswith("//") or s.startswith("#[")):
            continue
        low = s.lower()
        if ("long" in low or "length" in low) and (
            "because" in low or "reason" in low or ":" in low
        ):
            return True
    return False


def functions(path):
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    state = {"block": 0, "str": False, "raw": False, "hashes": 0}
    code = [strip(l, state) for l in lines]
    k = 0
    while k < len(code):
        m = FN.match(code[k])
        if not m:
            k += 1
            continue
        # Find the body's opening brace (or a `;`: a declaration without a body).
        depth = 0
        j = k
        opened = False
        while j < len(code):
            for ch in code[j]:
                if ch == "{":
                    depth += 1
                    opened = True
                elif ch == "}":
                    depth -= 1
                elif ch == ";" and not opened and depth == 0:
                    break
            else:
                if opened and depth == 0:
                    break
                j += 1
                continue
            if opened and depth == 0:
                break
            if not opened:
                break
            j += 1
        if opened:
            yield m.group(7), k, j, lines
        k += 1


def main(argv):
    limit = 150
    dirs = []
    it = iter(argv)
    for a in it:
        if a == "--limit":
            limit = int(next(it))
        else:
            dirs.append(a)
    dirs = dirs or ["crates", "src"]
    missing = 0
    rows = []
    for d in dirs:
        for path in sorted(Path(d).rglob("*.rs")):
            if "target" in path.parts:
                continue
            for name, start, end, lines in functions(path):
                length = end - start + 1
                if length > limit:
                    ok = reason(lines, start, end)
                    missing += not ok
                    rows.append((length, f"{path}:{start + 1}", name, ok))
    for length, place, name, ok in sorted(rows, reverse=True):
        print(f"{length:5d}  {'reason ' if ok else 'NO REASON'}  {place}  {name}")
    print(f"{len(rows)} functions longer than {limit} lines, {missing} without a reason")
    return min(missing, 100)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
