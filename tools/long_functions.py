#!/usr/bin/env python3
"""Functions longer than a limit (default 80 lines, signature to closing brace), tests left
out, with the doc comment above each — where a long function must say why it is long.

    python3 tools/long_functions.py runtime/src/diagnose [runtime/src/ident ...] [--max 80]
"""

import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from import_graph import strip_comments_and_strings  # noqa: E402


def blank_out(text):
    """Comments and literals blanked with line breaks kept, so line numbers stay."""
    code = strip_comments_and_strings(text)
    return code


def main():
    args = sys.argv[1:]
    limit = 80
    if "--max" in args:
        i = args.index("--max")
        limit = int(args[i + 1])
        del args[i : i + 2]
    for root in args:
        for dirpath, _, files in os.walk(root):
            for f in sorted(files):
                path = os.path.join(dirpath, f)
                if not f.endswith(".rs") or f == "tests.rs" or "/tests/" in path + "/":
                    continue
                report(path, limit)


def report(path, limit):
    text = open(path, encoding="utf-8").read()
    lines = text.split("\n")
    # Line-preserving code view: strip each comment/literal but keep newlines.
    code_lines = strip_keep_lines(text).split("\n")
    in_test = cfg_test_ranges(code_lines)
    for i, line in enumerate(code_lines):
        if not re.search(r"\bfn\s+\w+", line) or in_test[i]:
            continue
        # The body: from the first `{` after the signature to its match.
        depth, start, end = 0, None, None
        for j in range(i, len(code_lines)):
            for ch in code_lines[j]:
                if ch == ";" and start is None and depth == 0:
                    end = -1
                    break
                if ch == "{":
                    depth += 1
                    start = j if start is None else start
                elif ch == "}":
                    depth -= 1
                    if depth == 0 and start is not None:
                        end = j
                        break
            if end is not None:
                break
        if end is None or end < 0:
            continue
        n = end - i + 1
        if n > limit:
            k = i - 1
            doc = []
            while k >= 0 and (lines[k].strip().startswith("///") or lines[k].strip().startswith("#[") or lines[k].strip().startswith("//")):
                doc.insert(0, lines[k].strip())
                k -= 1
            name = re.search(r"\bfn\s+(\w+)", line).group(1)
            print(f"{path}:{i + 1}: fn {name}: {n} lines")
            for d in doc:
                print(f"    {d}")


def strip_keep_lines(text):
    out = []
    for piece in re.split(r"(\n)", text):
        out.append(piece)
    # Blank comments and literals but keep every newline.
    code = []
    i, n = 0, len(text)
    while i < n:
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i)
            j = n if j < 0 else j + 2
            code.append("\n" * text.count("\n", i, j))
            i = j
        elif text[i] == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            code.append('""' + "\n" * text.count("\n", i, j))
            i = j + 1
        elif text[i] == "'" and re.match(r"'(\\.[^']*|[^\\'])'", text[i:]):
            m = re.match(r"'(\\.[^']*|[^\\'])'", text[i:])
            code.append("' '")
            i += m.end()
        else:
            code.append(text[i])
            i += 1
    return "".join(code)


def cfg_test_ranges(code_lines):
    """Per line, whether it lies in a `#[cfg(test)]` item."""
    flags = [False] * len(code_lines)
    i = 0
    while i < len(code_lines):
        if "#[cfg(test)]" in code_lines[i]:
            depth, started = 0, False
            j = i
            while j < len(code_lines):
                flags[j] = True
                for ch in code_lines[j]:
                    if ch == "{":
                        depth += 1
                        started = True
                    elif ch == "}":
                        depth -= 1
                if (started and depth == 0) or (not started and code_lines[j].rstrip().endswith(";")):
                    break
                j += 1
            i = j + 1
        else:
            i += 1
    return flags


if __name__ == "__main__":
    main()
