#!/usr/bin/env python3
"""The tree's structural rules, checked from the source text.

1. No import circle between the files of the codec crate (`codec/src`),
   nor between the top-level modules of `src/` (`me`, `flow`, `encode`,
   ...): an edge A -> B is any path `crate::B...` written in A (a `use` or
   a path in code), test modules left out.
2. No function longer than 100 lines outside tests.
3. No CPU-feature test (`at_least(`, `is_x86_feature_detected!`) outside
   `cpu.rs` and the `dsp` modules that build the kernel tables.

Usage: python3 .ci/structure.py [--graph]   (exit 1 on a violation;
--graph prints every edge).
"""

import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MAX_FN_LINES = 100


def rust_files(top):
    for base, dirs, files in os.walk(top):
        dirs.sort()
        for f in sorted(files):
            if f.endswith(".rs"):
                yield os.path.join(base, f)


def strip_comments_and_strings(text):
    """The text with comments and string/char literals blanked (newlines kept)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "r" and re.match(r'r#*"', text[i:i + 10]) and not re.match(r"\w", text[i - 1:i] or " "):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            end = text.find('"' + hashes, i + len(hashes) + 2)
            end = n if end < 0 else end + 1 + len(hashes)
            out.append(re.sub(r"[^\n]", " ", text[i:end]))
            i = end
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append(re.sub(r"[^\n]", " ", text[i:j + 1]))
            i = j + 1
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", text[i:i + 4]) or re.match(r"'\\u\{[0-9a-fA-F]+\}'", text[i:i + 12]):
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", text[i:])
            out.append(" " * len(m.group(0)))
            i += len(m.group(0))
        else:
            out.append(c)
            i += 1
    return "".join(out)


def matching_brace(text, open_at):
    depth = 0
    for j in range(open_at, len(text)):
        if text[j] == "{":
            depth += 1
        elif text[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(text) - 1


def without_tests(text):
    """The text with every `#[cfg(test)]` item blanked (newlines kept)."""
    while True:
        m = re.search(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{", text)
        if not m:
            return text
        end = matching_brace(text, m.end() - 1)
        text = text[:m.start()] + re.sub(r"[^\n]", " ", text[m.start():end + 1]) + text[end + 1:]


def paths_from(text, anchor):
    """Every path written after `anchor` (`crate::`, `super::`), as a list
    of its segments, `{a, b::c}` groups expanded."""
    out = []

    def expand(prefix, rest):
        rest = rest.lstrip()
        if rest.startswith("{"):
            end = matching_brace(rest, 0)
            depth, item = 0, ""
            for ch in rest[1:end] + ",":
                if ch == "{":
                    depth += 1
                elif ch == "}":
                    depth -= 1
                if ch == "," and depth == 0:
                    if item.strip():
                        expand(prefix, item)
                    item = ""
                else:
                    item += ch
            return
        m = re.match(r"((?:\w+\s*::\s*)*)(\w+|\{)", rest)
        if not m:
            return
        segs = [x for x in re.split(r"\s*::\s*", m.group(1)) if x]
        if m.group(2) == "{":
            expand(prefix + segs, rest[m.end() - 1:])
        else:
            out.append(prefix + segs + [m.group(2)])

    for m in re.finditer(r"\b" + anchor + r"\s*::\s*", text):
        expand([], text[m.end():])
    return out


def crate_paths(text):
    """The first segment of every `crate::...` path (kept for the module level)."""
    return [p[0] for p in paths_from(text, "crate") if p]


def reexports(lib_text):
    """name -> module for `pub use module::{names}` in a crate root."""
    names = {}
    for m in re.finditer(r"pub\s+use\s+(\w+)\s*::\s*(\{[^}]*\}|\w+)", lib_text):
        module, items = m.group(1), m.group(2).strip("{}")
        for item in items.split(","):
            item = item.strip().split(" as ")[-1].strip()
            if item:
                names[item] = module
    return names


def module_of(path, top, file_level):
    rel = os.path.relpath(path, top)
    parts = rel[:-3].split(os.sep)
    if file_level:
        if parts[-1] == "mod":
            parts = parts[:-1]
        return "::".join(parts)
    return parts[0]


def edges(top, file_level, skip):
    lib = open(os.path.join(top, "lib.rs")).read()
    alias = reexports(lib)
    modules = set()
    for f in rust_files(top):
        m = module_of(f, top, file_level)
        if m not in skip:
            modules.add(m if file_level else m.split("::")[0])
    graph = {}
    for f in rust_files(top):
        me = module_of(f, top, file_level)
        if me in skip:
            continue
        text = without_tests(strip_comments_and_strings(open(f).read()))
        found = [p for p in paths_from(text, "crate")]
        if file_level:
            # `super::x` from a/b.rs (module a::b) is a::x; from a/mod.rs (a), the crate's x.
            parent = me.split("::")[:-1] if not f.endswith("mod.rs") else me.split("::")[:-1]
            found += [parent + p for p in paths_from(text, "super")]
        for path in found:
            if not path:
                continue
            target = None
            if file_level:
                for n in range(len(path), 0, -1):
                    cand = "::".join(path[:n])
                    if cand in modules:
                        target = cand
                        break
                if target is None:
                    target = alias.get(path[0])
            else:
                target = path[0] if path[0] in modules else alias.get(path[0])
            if target and target != me and target in modules and target not in skip:
                graph.setdefault(me, set()).add(target)
    return graph


def cycles(graph):
    """The strongly connected components of more than one node (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
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

    for v in sorted(set(graph) | {w for ws in graph.values() for w in ws}):
        if v not in index:
            visit(v)
    return out


def long_functions(path):
    text = without_tests(strip_comments_and_strings(open(path).read()))
    found = []
    for m in re.finditer(r"\bfn\s+(\w+)[^;{]*\{", text):
        # `fn` types in signatures have no body; a body's brace follows `)` or a return type.
        start = m.end() - 1
        end = matching_brace(text, start)
        lines = text.count("\n", m.start(), end) + 1
        if lines > MAX_FN_LINES:
            found.append((text.count("\n", 0, m.start()) + 1, m.group(1), lines))
    return found


def feature_tests(path):
    text = without_tests(strip_comments_and_strings(open(path).read()))
    return [text.count("\n", 0, m.start()) + 1
            for m in re.finditer(r"\bat_least\s*\(|is_x86_feature_detected!", text)]


def main():
    show = "--graph" in sys.argv
    bad = 0
    for name, top, file_level in [("codec/src", os.path.join(ROOT, "codec/src"), True),
                                  ("src", os.path.join(ROOT, "src"), False)]:
        graph = edges(top, file_level, skip={"lib", "main"} if not file_level else {"lib"})
        if show:
            for a in sorted(graph):
                print(f"{name}: {a} -> {', '.join(sorted(graph[a]))}")
        for comp in cycles(graph):
            bad += 1
            inner = {a: sorted(b for b in graph.get(a, ()) if b in comp) for a in comp}
            print(f"import circle in {name}: " + "; ".join(f"{a} -> {', '.join(bs)}" for a, bs in inner.items()))
    for top in ["codec/src", "src", "python/src", "benches", "fuzz/fuzz_targets"]:
        for f in rust_files(os.path.join(ROOT, top)):
            rel = os.path.relpath(f, ROOT)
            for line, fname, n in long_functions(f):
                bad += 1
                print(f"{rel}:{line}: fn {fname} is {n} lines (at most {MAX_FN_LINES} outside tests)")
            base = os.path.basename(f)
            in_dsp = base in ("cpu.rs", "dsp.rs") or f"{os.sep}dsp{os.sep}" in f
            if not in_dsp:
                for line in feature_tests(f):
                    bad += 1
                    print(f"{rel}:{line}: CPU-feature test outside cpu.rs and the dsp modules")
    if bad:
        sys.exit(1)
    print("structure: no import circle, no function over", MAX_FN_LINES, "lines, CPU features tested only in the dsp tables")


if __name__ == "__main__":
    main()
