#!/usr/bin/env python3
"""The module import graph of the workspace's library crates, and its circles.

    python3 tools/import_graph.py            # every crate
    python3 tools/import_graph.py runtime    # crates whose source folder starts so

Reads every non-test module of a crate (from `lib.rs` through its `mod` lines; `#[cfg(test)]`
modules and inline `mod tests { .. }` left out) and the paths it names: `use` lines and paths
in code that start with `crate::` or `super::`. A path is resolved to the module that defines
the item, following `pub use` re-exports. Printed:

- circles between sibling modules: at each folder, the children are the nodes and a child
  depends on another when any file inside it names an item defined inside the other; a
  strongly connected set of two or more children is a circle;
- imports through a parent's re-export: a child that reaches an item of its own sibling
  through the parent (`use super::Item` where the parent only re-exports it), which makes
  child -> parent -> child;
- glob imports (`use super::*`, ...) outside tests.

Exits 1 when a circle is found. A checking aid, not part of the build.
"""

import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CRATES = {
    "dynid_ir": "dsl-parser/ir/src",
    "dsl_parser": "dsl-parser/src",
    "dynid_runtime": "runtime/src",
    "dynid": "src",
}


def strip_comments_and_strings(text):
    """Code only: comments removed, string and char literals emptied (`""`, `' '`)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
        elif c == "r" and re.match(r'r#*"', text[i:]) and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'r(#*)"', text[i:])
            end = text.find('"' + m.group(1), i + m.end())
            out.append('""')
            i = n if end < 0 else end + 1 + len(m.group(1))
        elif c == '"':
            i += 1
            while i < n and text[i] != '"':
                i += 2 if text[i] == "\\" else 1
            out.append('""')
            i += 1
        elif c == "'" and re.match(r"'(\\.[^']*|[^\\'])'", text[i:]):
            m = re.match(r"'(\\.[^']*|[^\\'])'", text[i:])
            out.append("' '")
            i += m.end()
        else:
            out.append(c)
            i += 1
    return "".join(out)


def drop_test_blocks(text):
    """Remove `#[cfg(test)]` items (inline modules and functions) by brace matching."""
    out = []
    i = 0
    while True:
        m = re.search(r"#\[cfg\(test\)\]", text[i:])
        if not m:
            out.append(text[i:])
            break
        start = i + m.start()
        out.append(text[i:start])
        j = i + m.end()
        # The item ends at the first `;` before any `{`, or at the matching `}`.
        semi = text.find(";", j)
        brace = text.find("{", j)
        if brace < 0 or (0 <= semi < brace):
            i = semi + 1
            continue
        depth = 0
        k = brace
        while k < len(text):
            if text[k] == "{":
                depth += 1
            elif text[k] == "}":
                depth -= 1
                if depth == 0:
                    break
            k += 1
        i = k + 1
    return "".join(out)


def expand_use(tree):
    """`a::{b, c::{d, e as f}}` -> [[a,b],[a,c,d],[a,c,e]]; `x::self` -> [x]."""
    tree = re.sub(r"\s+as\s+\w+", "", tree)
    tree = re.sub(r"\s+", "", tree)

    def split_top(s):
        parts, depth, cur = [], 0, ""
        for ch in s:
            depth += {"{": 1, "}": -1}.get(ch, 0)
            if ch == "," and depth == 0:
                parts.append(cur)
                cur = ""
            else:
                cur += ch
        if cur:
            parts.append(cur)
        return parts

    def go(prefix, s):
        i = s.find("{")
        if i < 0:
            segs = [x for x in s.split("::") if x]
            if segs and segs[-1] == "self":
                segs = segs[:-1]
            return [prefix + segs]
        head = [x for x in s[:i].split("::") if x]
        res = []
        for part in split_top(s[i + 1 : s.rfind("}")]):
            res += go(prefix + head, part)
        return res

    return go([], tree)


class Module:
    def __init__(self, path, file):
        self.path = path  # tuple of segments from the crate root
        self.file = file
        self.children = {}  # name -> Module
        self.items = set()  # names defined here
        self.reexports = {}  # name -> absolute path (tuple) it re-exports
        self.uses = []  # (absolute path tuple, is_use_line)
        self.globs = []


def parse_crate(crate, src):
    mods = {}

    def load(path, file, dir_for_children):
        text = open(file, encoding="utf-8").read()
        code = drop_test_blocks(strip_comments_and_strings(text))
        m = Module(path, file)
        mods[path] = m
        for name in re.findall(
            r"\b(?:pub(?:\([^)]*\))?\s+)?(?:unsafe\s+)?(?:async\s+)?(?:const\s+)?(?:fn|struct|enum|trait|type|const|static|union|macro_rules!)\s+(\w+)",
            code,
        ):
            m.items.add(name)
        for pm in re.finditer(r"(#\[path\s*=\s*\"[^\"]*\"\]\s*)?\b(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;", code):
            name = pm.group(2)
            if pm.group(1):
                continue
            cand = [os.path.join(dir_for_children, name + ".rs"), os.path.join(dir_for_children, name, "mod.rs")]
            f = next((c for c in cand if os.path.exists(c)), None)
            if f is None:
                continue
            m.children[name] = load(path + (name,), f, os.path.join(dir_for_children, name))
            m.items.add(name)
        # `use` statements.
        for um in re.finditer(r"\b(pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", code):
            public = bool(um.group(1))
            for segs in expand_use(um.group(2)):
                if not segs:
                    continue
                if segs[-1] == "*":
                    m.globs.append("::".join(segs))
                    segs = segs[:-1]
                    glob = True
                else:
                    glob = False
                ab = absolutize(path, segs, m)
                if ab is None:
                    continue
                if public and not glob:
                    alias = segs[-1]
                    am = re.search(r"\b" + re.escape(segs[-1]) + r"\s+as\s+(\w+)", um.group(2))
                    if am:
                        alias = am.group(1)
                    m.reexports[alias] = ab
                m.uses.append((ab, True))
        # Paths in code.
        rest = re.sub(r"\b(pub(?:\([^)]*\))?\s+)?use\s+[^;]+;", "", code)
        for pm in re.finditer(r"\b((?:crate|super|self)(?:::(?:super|\w+))+)", rest):
            segs = pm.group(1).split("::")
            ab = absolutize(path, segs, m)
            if ab is not None:
                m.uses.append((ab, False))
        return m

    def absolutize(path, segs, m):
        segs = [re.sub(r"\s.*", "", s) for s in segs]
        if segs[0] == "crate":
            return tuple(segs[1:])
        if segs[0] in ("super", "self"):
            base = list(path)
            # `path` is the module of this file; `super` goes one up.
            i = 0
            while i < len(segs) and segs[i] in ("super", "self"):
                if segs[i] == "super":
                    base = base[:-1]
                i += 1
            return tuple(base + segs[i:])
        # Relative to this module: a child module or an item declared here.
        return ("<rel>", tuple(path), tuple(segs))

    root_file = os.path.join(src, "lib.rs")
    load((), root_file, src)
    # Relative paths (`use child::Item`) resolved now that children are known.
    for m in mods.values():
        fixed = []
        for ab, is_use in m.uses:
            if ab and ab[0] == "<rel>":
                _, base, segs = ab
                if segs and segs[0] in m.children:
                    fixed.append((base + segs, is_use))
                continue
            fixed.append((ab, is_use))
        m.uses = fixed
        for k, v in list(m.reexports.items()):
            if v and v[0] == "<rel>":
                _, base, segs = v
                if segs and segs[0] in m.children:
                    m.reexports[k] = base + segs
                else:
                    del m.reexports[k]
    return mods


def resolve(mods, ab, depth=0):
    """Module path defining the item `ab` names, and the modules whose re-export it went through."""
    mod = ()
    i = 0
    while i < len(ab) and mod + (ab[i],) in mods:
        mod = mod + (ab[i],)
        i += 1
    if i == len(ab) or depth > 20:
        return mod, []
    name = ab[i]
    m = mods[mod]
    if name in m.reexports and name not in m.items:
        target = m.reexports[name] + tuple(ab[i + 1 :])
        inner, via = resolve(mods, target, depth + 1)
        return inner, [mod] + via
    return mod, []


def tarjan(nodes, edges):
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in nodes:
        if v not in index:
            strong(v)
    return out


def main():
    sys.setrecursionlimit(10000)
    only = sys.argv[1:]
    found = False
    for crate, src in CRATES.items():
        if only and not any(src.startswith(o) for o in only):
            continue
        mods = parse_crate(crate, os.path.join(ROOT, src))
        # edges[parent][child_a] = {child_b: [example file -> item]}
        edges = {}
        via_parent = []
        for m in mods.values():
            for ab, _ in m.uses:
                target, via = resolve(mods, ab)
                src_p, dst_p = m.path, target
                # Lowest common ancestor.
                k = 0
                while k < min(len(src_p), len(dst_p)) and src_p[k] == dst_p[k]:
                    k += 1
                if k < len(src_p) and k < len(dst_p):
                    parent = src_p[:k]
                    a, b = src_p[k], dst_p[k]
                    edges.setdefault(parent, {}).setdefault(a, {}).setdefault(b, set()).add(
                        (os.path.relpath(m.file, ROOT), "::".join(ab))
                    )
                    # Reached through an ancestor's re-export that is the common parent.
                    for v in via:
                        if v == parent or (len(v) < len(src_p) and src_p[: len(v)] == v):
                            via_parent.append((os.path.relpath(m.file, ROOT), "::".join(ab), "::".join(target)))
                            break
        print(f"== {crate} ({src}): {len(mods)} modules")
        for parent, e in sorted(edges.items()):
            nodes = sorted(set(e) | {b for x in e.values() for b in x})
            adj = {a: sorted(bs) for a, bs in e.items()}
            for comp in tarjan(nodes, adj):
                found = True
                where = "::".join(parent) or "<root>"
                print(f"circle in {where}: {' <-> '.join(comp)}")
                for a in comp:
                    for b in adj.get(a, ()):
                        if b in comp:
                            ex = sorted(e[a][b])[:3]
                            print(f"    {a} -> {b}: " + "; ".join(f"{f} ({p})" for f, p in ex))
        for f, p, t in sorted(set(via_parent)):
            print(f"through a parent's re-export: {f}: {p} (defined in {t})")
        for m in sorted(mods.values(), key=lambda m: m.file):
            for g in m.globs:
                print(f"glob import: {os.path.relpath(m.file, ROOT)}: use {g}")
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
