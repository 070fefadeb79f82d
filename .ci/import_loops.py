#!/usr/bin/env python3
"""Import loops between the files of each crate, and how the lines spread over crates.

A file imports another when it names one of its items through `crate::...`, `super::...`
or `self::...` (in a `use` or inline in code; comments and `#[cfg(test)]` modules do not
count, nor do `mod` declarations). A loop is a strongly connected component of that graph
with more than one file: every file in it reaches every other through imports. The check
fails (exit 1) when a loop has more than --max-loop files (3), when a crate holds more
than --max-share of the workspace's lines (35%), or when more than --max-long files pass
--long lines (2 files over 600 lines).

    python3 .ci/import_loops.py            # the report, and the check
    python3 .ci/import_loops.py --with-tests   # test modules' imports count too

Lines are those of the `.rs` files git tracks under each crate's folder (sources, tests,
examples, benches).
"""

import argparse
import os
import re
import subprocess
import sys
from collections import defaultdict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def workspace_crates():
    """The member folders named in the root Cargo.toml."""
    text = open(os.path.join(ROOT, "Cargo.toml")).read()
    m = re.search(r"members\s*=\s*\[(.*?)\]", text, re.S)
    return re.findall(r'"([^"]+)"', m.group(1))


def module_files(src):
    """Module path (tuple) -> file, for every module file under `src` (lib.rs is ())."""
    mods = {}
    for dirpath, _, files in os.walk(src):
        for f in files:
            if not f.endswith(".rs"):
                continue
            path = os.path.join(dirpath, f)
            rel = os.path.relpath(path, src)[:-3].split(os.sep)
            if rel in (["lib"], ["main"]):
                key = ("<root:%s>" % rel[0],)
            elif rel[-1] == "mod":
                key = tuple(rel[:-1])
            else:
                key = tuple(rel)
            mods[key] = path
    return mods


def strip_comments(line):
    """The line without a `//` comment (strings holding `//` are rare enough here)."""
    i = line.find("//")
    return line if i < 0 else line[:i]


def use_paths(tree):
    """Every full path of a `use` tree (`a::{b, c::{d, e}}` -> a::b, a::c::d, a::c::e)."""
    tree = tree.strip()
    depth = 0
    for i, ch in enumerate(tree):
        if ch == "{":
            if depth == 0:
                prefix = tree[:i].rstrip(":").strip()
                inner = tree[i + 1 : tree.rindex("}")]
                parts, d, start = [], 0, 0
                for j, c in enumerate(inner):
                    if c == "{":
                        d += 1
                    elif c == "}":
                        d -= 1
                    elif c == "," and d == 0:
                        parts.append(inner[start:j])
                        start = j + 1
                parts.append(inner[start:])
                out = []
                for p in parts:
                    if p.strip():
                        out += [prefix + "::" + q if prefix else q for q in use_paths(p)]
                return out
            depth += 1
    return [tree.split(" as ")[0].strip()]


def references(path, with_tests):
    """(module path of the code, referenced path) for every crate-relative path in a file."""
    lines = open(path, encoding="utf-8").read().split("\n")
    code = []  # (inline module stack, text)
    stack = []  # (name, depth at which it opened, is_test)
    depth = 0
    pending_test = False
    for line in lines:
        text = strip_comments(line)
        if re.match(r"\s*#\[cfg\(test\)\]", text):
            pending_test = True
            continue
        m = re.match(r"\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*\{", text)
        if m:
            stack.append((m.group(1), depth, pending_test))
            pending_test = False
        elif text.strip() and not text.strip().startswith("#["):
            pending_test = False
        if with_tests or not any(t for _, _, t in stack):
            code.append((tuple(n for n, _, _ in stack), text))
        depth += text.count("{") - text.count("}")
        while stack and depth <= stack[-1][1]:
            stack.pop()
    refs = []
    # `use` statements may span lines: join the code of each inline module.
    joined = defaultdict(list)
    for inner, text in code:
        joined[inner].append(text)
    for inner, texts in joined.items():
        body = "\n".join(texts)
        for m in re.finditer(r"\buse\s+([^;]*);", body, re.S):
            for p in use_paths(m.group(1)):
                refs.append((inner, p))
        body = re.sub(r"\buse\s+[^;]*;", "", body, flags=re.S)
        for m in re.finditer(r"(?<![\w:])((?:crate|super|self|[a-z_][a-z0-9_]*)(?:::(?:super|\w+))+)", body):
            refs.append((inner, m.group(1)))
    return refs


def reexports(path, key):
    """`pub use` items of a module file: name -> the path it re-exports (as written),
    `*` -> the module a glob re-exports."""
    out = {}
    text = "\n".join(strip_comments(l) for l in open(path, encoding="utf-8").read().split("\n"))
    for m in re.finditer(r"\bpub(?:\([^)]*\))?\s+use\s+([^;]*);", text, re.S):
        for p in use_paths(m.group(1)):
            parts = p.split(" as ")
            target = parts[0].strip()
            name = parts[1].strip() if len(parts) > 1 else target.split("::")[-1]
            out[name] = target
    return out


def resolve(here, inner, ref, mods, exports=None, depth=0):
    """The module file a path names (following `pub use` re-exports to where the item
    is defined), or None when it leaves the crate."""
    segs = ref.split("::")
    base = list(here) + list(inner)
    if segs[0] == "crate":
        cur, segs = [], segs[1:]
    elif segs[0] in ("super", "self"):
        cur = base
        while segs and segs[0] in ("super", "self"):
            if segs[0] == "super":
                cur = cur[:-1]
            segs = segs[1:]
    elif tuple(base + segs[:1]) in mods:
        # A path relative to this module: one of its child modules (`use cluster::x`).
        cur = base
    else:
        return None
    full = cur + segs
    for n in range(len(full), -1, -1):
        key = tuple(full[:n]) if n else None
        file = mods.get(key) if n else (mods.get(("<root:lib>",)) or mods.get(("<root:main>",)))
        if file is None:
            continue
        rest = full[n:]
        if exports is not None and rest and depth < 8:
            table = exports.get(file, {})
            target = table.get(rest[0])
            if target is not None:
                again = resolve(key or (), (), "::".join([target] + rest[1:]), mods, exports, depth + 1)
                if again:
                    return again
            if "*" in table:
                for glob in [t for n2, t in table.items() if n2 == "*"]:
                    again = resolve(key or (), (), glob.rstrip(":*") + "::" + "::".join(rest), mods, exports, depth + 1)
                    if again and again != file:
                        return again
        return file
    return None


def sccs(graph):
    """Tarjan's strongly connected components."""
    index, low, on, st, out = {}, {}, set(), [], []
    counter = [0]
    sys.setrecursionlimit(10000)

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        st.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = st.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            out.append(comp)

    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def tracked_lines(folder):
    git = subprocess.run(["git", "ls-files", folder], cwd=ROOT, capture_output=True, text=True)
    if git.returncode == 0:
        files = git.stdout.split()
    else:
        # Not a git checkout (an exported tree): every file under the folder.
        files = [
            os.path.relpath(os.path.join(d, f), ROOT)
            for d, _, fs in os.walk(os.path.join(ROOT, folder))
            if "/target" not in d
            for f in fs
        ]
    total, long = 0, []
    for f in files:
        if f.endswith(".rs"):
            n = sum(1 for _ in open(os.path.join(ROOT, f), encoding="utf-8"))
            total += n
            long.append((n, f))
    return total, long


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--with-tests", action="store_true", help="count the imports of #[cfg(test)] modules too")
    ap.add_argument("--max-loop", type=int, default=3)
    ap.add_argument("--max-share", type=float, default=35.0)
    ap.add_argument("--long", type=int, default=600)
    ap.add_argument("--max-long", type=int, default=2)
    ap.add_argument("--root", help="the workspace to read (default: this checkout)")
    args = ap.parse_args()
    global ROOT
    ROOT = os.path.abspath(args.root) if args.root else ROOT
    failed = False
    worst = 0
    print("import loops (files that import each other, by crate):")
    for crate in workspace_crates():
        src = os.path.join(ROOT, crate, "src")
        if not os.path.isdir(src):
            continue
        mods = module_files(src)
        by_file = {f: k for k, f in mods.items()}
        exports = {f: reexports(f, k) for f, k in by_file.items()}
        graph = {f: set() for f in mods.values()}
        for f, key in by_file.items():
            if not args.with_tests and "tests" in key:
                continue
            here = () if key[0].startswith("<root") else key
            for inner, ref in references(f, args.with_tests):
                t = resolve(here, inner, ref, mods, exports)
                if t and t != f:
                    graph[f].add(t)
        loops = sorted((c for c in sccs(graph) if len(c) > 1), key=len, reverse=True)
        sizes = [len(c) for c in loops]
        worst = max([worst] + sizes)
        print(f"  {crate}: {len(mods)} files, loops of {sizes or 'none'}")
        for c in loops:
            names = sorted(os.path.relpath(f, ROOT) for f in c)
            mark = "  TOO BIG" if len(c) > args.max_loop else ""
            print(f"    {len(c)}: {' '.join(names)}{mark}")
            failed |= len(c) > args.max_loop
    print(f"largest loop: {worst} files (at most {args.max_loop})")
    counts, long = {}, []
    for crate in workspace_crates():
        n, files = tracked_lines(crate)
        counts[crate] = n
        long += files
    total = sum(counts.values())
    print(f"lines of Rust by crate ({total} in all; at most {args.max_share:.0f}% each):")
    for crate, n in sorted(counts.items(), key=lambda kv: -kv[1]):
        share = 100.0 * n / total
        mark = "  TOO BIG" if share > args.max_share else ""
        print(f"  {crate:10} {n:6} {share:5.1f}%{mark}")
        failed |= share > args.max_share
    over = sorted((x for x in long if x[0] > args.long), reverse=True)
    print(f"files over {args.long} lines ({len(over)}; at most {args.max_long}):")
    for n, f in over:
        print(f"  {n:6} {f}")
    failed |= len(over) > args.max_long
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
