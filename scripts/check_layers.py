#!/usr/bin/env python3
"""Checks that the workspace's dependencies only point down (ARCHITECTURE.md, "Layers").

Between crates it reads `cargo metadata`: the workspace crates' dependencies on each other must
follow the crate order written in ARCHITECTURE.md, and a crate must use every workspace crate it
declares. Between the modules of a crate it reads the code's own paths (`use crate::…`,
`super::…`, `self::…`, a child module's name, and the same paths inside code), resolves a name a
module re-exports to the module that defines it, and projects every reference onto the modules
that share a parent: `a::x` using `b::y` is an arrow a -> b among the children of the crate
root, and a child using an item its parent defines itself is an arrow to the parent's own code
(`a/(own)`). Such arrows must not form a circle, and among the modules of a crate whose layers
ARCHITECTURE.md lists they must not point to a higher layer. An arrow listed there as a known
exception is allowed; a listed exception that the code no longer has is an error too, so the
list only shrinks.

Usage: scripts/check_layers.py [--root DIR] [--architecture FILE] [--graph CRATE]
Exit status 0 when everything points down, 1 with each violation printed otherwise.
"""

import argparse
import json
import os
import re
import subprocess
import sys
from collections import defaultdict

OWN = "(own)"
ITEM_KEYWORDS = {"fn", "struct", "enum", "trait", "type", "const", "static", "union"}
PATH_STARTS = {"crate", "super", "self"}


# ---------------------------------------------------------------- reading Rust source text


def strip_code(text):
    """The text with comments, string and char literals blanked (line structure kept)."""
    out = []
    i, n = 0, len(text)
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
                    out.append("\n" if text[i] == "\n" else "")
                    i += 1
        elif c == "r" and re.match(r'r#*"', text[i:i + 8]) and not _ident_char(text, i - 1):
            hashes = len(re.match(r"r(#*)", text[i:]).group(1))
            end = text.find('"' + "#" * hashes, i + 2 + hashes)
            end = n if end < 0 else end + 1 + hashes
            out.append('""' + "\n" * text.count("\n", i, end))
            i = end
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j + 1
        elif c == "'":
            if i + 1 < n and text[i + 1] == "\\":
                j = text.find("'", i + 2)
                i = n if j < 0 else j + 1
                out.append("' '")
            elif i + 2 < n and text[i + 2] == "'":
                i += 3
                out.append("' '")
            else:
                i += 1  # a lifetime
        else:
            out.append(c)
            i += 1
    return "".join(out)


def _ident_char(text, i):
    return i >= 0 and (text[i].isalnum() or text[i] == "_")


TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*|::|\S")


def tokens(text):
    return TOKEN.findall(strip_code(text))


def path_attribute(text_before):
    """The `#[path = "…"]` attribute directly before a `mod` item, if any."""
    m = re.search(r'#\[path\s*=\s*"([^"]+)"\]\s*(?:#\[[^\]]*\]\s*)*(?:pub(?:\([^)]*\))?\s+)?mod\s+\w+\s*;\s*$',
                  text_before)
    return m.group(1) if m else None


# ---------------------------------------------------------------- one crate's module tree


class Module:
    def __init__(self, path, file):
        self.path = path  # tuple of names from the crate root
        self.file = file
        self.children = set()
        self.defined = set()
        self.reexports = {}  # name -> absolute path (tuple) it stands for
        self.glob_reexports = []  # absolute module paths
        self.aliases = {}  # name -> absolute path, from `use`
        self.glob_super = False
        self.refs = []  # (absolute path tuple, line text) used by this module's code


def parse_use_tree(toks, i):
    """Parses a use tree from toks[i]; returns (list of (segments, alias)), next index."""
    prefix = []
    while i < len(toks):
        t = toks[i]
        if t == "{":
            items, i = [], i + 1
            while toks[i] != "}":
                sub, i = parse_use_tree(toks, i)
                items.extend(sub)
                if toks[i] == ",":
                    i += 1
            return [(prefix + s, a) for s, a in items], i + 1
        if t == "*":
            return [(prefix + ["*"], None)], i + 1
        if t == "::":
            i += 1
            continue
        if re.match(r"[A-Za-z_]", t):
            prefix.append(t)
            i += 1
            if i < len(toks) and toks[i] == "as":
                return [(prefix, toks[i + 1])], i + 2
            if i < len(toks) and toks[i] in (",", "}", ";"):
                return [(prefix, None)], i
            continue
        return [(prefix, None)], i
    return [(prefix, None)], i


class Scope:
    """The module the token at hand belongs to, as braces and inline `mod NAME {` open and
    close around it."""

    def __init__(self, module):
        self.stack = [(module, -1)]  # (module, brace depth its body opened at)
        self.depth = 0

    def current(self):
        return self.stack[-1][0]

    def brace(self, t):
        """Follows `{` and `}`; whether `t` was one."""
        if t == "{":
            self.depth += 1
        elif t == "}":
            self.depth -= 1
            if len(self.stack) > 1 and self.depth == self.stack[-1][1]:
                self.stack.pop()
        else:
            return False
        return True

    def enter(self, inner):
        """An inline module's body opens (its `{` read)."""
        self.stack.append((inner, self.depth))
        self.depth += 1


class Crate:
    def __init__(self, name, root_file):
        self.name = name
        self.modules = {}
        self.src_dir = os.path.dirname(root_file)
        self._load(root_file, (), is_dir_owner=True)
        for m in list(self.modules.values()):
            self._scan_refs(m)

    # -- pass 1: files, modules, definitions, use declarations
    def _load(self, file, path, is_dir_owner):
        text = open(file, encoding="utf-8").read()
        toks = tokens(text)
        module = Module(path, file)
        self.modules[path] = module
        child_dir = os.path.dirname(file) if is_dir_owner else os.path.splitext(file)[0]
        self._walk_items(toks, text, module, child_dir)

    def _walk_items(self, toks, text, module, child_dir):
        scope = Scope(module)
        i, mod_decl_count = 0, 0
        while i < len(toks):
            t = toks[i]
            cur = scope.current()
            if scope.brace(t):
                pass
            elif t == "mod" and i + 2 < len(toks) and toks[i + 2] in (";", "{") and _is_ident(toks[i + 1]):
                name = toks[i + 1]
                cur.children.add(name)
                cur.defined.add(name)
                if toks[i + 2] == "{":
                    inner = Module(cur.path + (name,), cur.file)
                    self.modules[inner.path] = inner
                    scope.enter(inner)
                    i += 3
                    continue
                mod_decl_count += 1
                sub_dir = child_dir if cur is module else os.path.join(child_dir, *cur.path[len(module.path):])
                self._load_child(text, name, mod_decl_count, sub_dir, cur.path + (name,))
            elif t == "use":
                trees, j = parse_use_tree(toks, i + 1)
                self._record_use(cur, trees, _is_pub(toks, i))
                i = j
                continue
            elif t in ITEM_KEYWORDS and i + 1 < len(toks) and _is_ident(toks[i + 1]):
                cur.defined.add(toks[i + 1])
            elif t == "macro_rules" and i + 2 < len(toks):
                cur.defined.add(toks[i + 2])
            i += 1

    def _load_child(self, text, name, nth, child_dir, path):
        # Find the n-th `mod NAME;` in the raw text to read a #[path] attribute before it.
        attr = None
        for m in re.finditer(r"\bmod\s+" + re.escape(name) + r"\s*;", text):
            attr = path_attribute(text[:m.end()])
            break
        if attr:
            file = os.path.normpath(os.path.join(child_dir, attr))
            if not os.path.isfile(file):
                return
            self._load(file, path, is_dir_owner=False)
            return
        for candidate, owner in ((os.path.join(child_dir, name + ".rs"), False),
                                 (os.path.join(child_dir, name, "mod.rs"), True)):
            if os.path.isfile(candidate):
                self._load(candidate, path, is_dir_owner=owner)
                return

    def _record_use(self, module, trees, pub):
        for segs, alias in trees:
            absolute = self._absolute(module, segs, in_use=True)
            if absolute is None:
                continue
            last = segs[-1]
            if last == "*":
                if segs[:-1] == ["super"]:
                    module.glob_super = True
                if pub:
                    module.glob_reexports.append(tuple(absolute[:-1]))
                else:
                    module.refs.append(tuple(absolute[:-1]) + ("*",))
                continue
            if last == "self":
                absolute, last = absolute[:-1], absolute[-2] if len(absolute) > 1 else None
                if last is None:
                    continue
            name = alias or last
            if pub:
                module.reexports[name] = tuple(absolute)
            module.aliases[name] = tuple(absolute)
            if not pub:
                module.refs.append(tuple(absolute))

    def _absolute(self, module, segs, in_use=False):
        """An absolute path (tuple) for segments read in `module`, or None when external."""
        if not segs:
            return None
        head = segs[0]
        if head == "crate":
            return list(segs[1:])
        if head in ("super", "self"):
            base = list(module.path)
            k = 0
            while k < len(segs) and segs[k] in ("super", "self"):
                if segs[k] == "super":
                    if not base:
                        return None
                    base.pop()
                k += 1
            return base + list(segs[k:])
        if head in module.children:
            return list(module.path) + list(segs)
        if not in_use:
            alias = self._alias(module, head)
            if alias is not None:
                return list(alias) + list(segs[1:])
        return None

    def _alias(self, module, name):
        m = module
        while m is not None:
            if name in m.aliases:
                return m.aliases[name]
            if not m.glob_super or not m.path:
                return None
            m = self.modules.get(m.path[:-1])
        return None

    # -- pass 2: paths inside code
    def _scan_refs(self, module):
        if module.path and self.modules.get(module.path[:-1]) is not None \
                and self.modules[module.path[:-1]].file == module.file:
            return  # an inline module: scanned with its file's module below
        text = open(module.file, encoding="utf-8").read()
        toks = tokens(text)
        scope = Scope(module)
        i = 0
        while i < len(toks):
            t = toks[i]
            cur = scope.current()
            if scope.brace(t):
                pass
            elif t == "mod" and i + 2 < len(toks) and toks[i + 2] == "{":
                scope.enter(self.modules.get(cur.path + (toks[i + 1],), cur))
                i += 3
                continue
            elif t == "use":
                while i < len(toks) and toks[i] != ";":
                    i += 1
            elif _is_ident(t) and i + 1 < len(toks) and toks[i + 1] == "::" \
                    and (i == 0 or toks[i - 1] not in ("::", "$", "'")):
                segs, j = [t], i + 1
                while j + 1 < len(toks) and toks[j] == "::" and _is_ident(toks[j + 1]):
                    segs.append(toks[j + 1])
                    j += 2
                absolute = self._absolute(cur, segs)
                if absolute is not None:
                    cur.refs.append(tuple(absolute))
                i = j
                continue
            elif t in cur.reexports and (i == 0 or toks[i - 1] not in ("::", ".", "$")):
                # A name the module re-exports (`pub use`) and also uses itself.
                cur.refs.append(cur.reexports[t])
            i += 1

    # -- resolving a path to the module whose own code holds it
    def locate(self, path, seen=0):
        """(module path, whole) for an absolute path: whole=True when it names a module."""
        path = tuple(p for p in path if p != "*")
        k = 0
        while k < len(path) and path[:k + 1] in self.modules:
            k += 1
        mod_path = path[:k]
        if k == len(path):
            return mod_path, True
        name = path[k]
        module = self.modules[mod_path]
        if seen < 8 and name in module.reexports and module.reexports[name] != path[:k + 1]:
            return self.locate(module.reexports[name] + path[k + 1:], seen + 1)
        if name not in module.defined and seen < 8:
            for g in module.glob_reexports:
                if g in self.modules and name in self.modules[g].defined:
                    return self.locate(g + (name,) + path[k + 1:], seen + 1)
        return mod_path, False

    def arrows(self):
        """{parent path: {(from, to): set of (file, to-path) examples}} among siblings."""
        levels = defaultdict(lambda: defaultdict(set))
        for module in self.modules.values():
            for ref in module.refs:
                target, whole = self.locate(ref)
                src = module.path
                k = 0
                while k < min(len(src), len(target)) and src[k] == target[k]:
                    k += 1
                parent = src[:k]
                a = src[k] if k < len(src) else OWN
                b = target[k] if k < len(target) else OWN
                if a == b or (a == OWN and b == OWN):
                    continue
                if b == OWN and whole:
                    continue  # naming an ancestor module itself, not its code
                levels[parent][(a, b)].add((os.path.relpath(module.file), "::".join(ref)))
        return levels


def _is_pub(toks, i):
    """Whether the `use` at toks[i] is `pub` or `pub(…)`: a re-export."""
    j = i - 1
    if j >= 0 and toks[j] == ")":
        while j >= 0 and toks[j] != "(":
            j -= 1
        j -= 1
    return j >= 0 and toks[j] == "pub"


def _is_ident(t):
    return bool(re.match(r"[A-Za-z_][A-Za-z0-9_]*$", t)) and t not in ("as",)


# ---------------------------------------------------------------- graphs


def circles(edges):
    """Strongly connected components with more than one node (Tarjan, iterative)."""
    graph = defaultdict(set)
    for a, b in edges:
        graph[a].add(b)
        graph.setdefault(b, set())
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            node, it = work[-1]
            nxt = next(it, None)
            if nxt is not None:
                if nxt not in index:
                    index[nxt] = low[nxt] = counter[0]
                    counter[0] += 1
                    stack.append(nxt)
                    on.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                elif nxt in on:
                    low[node] = min(low[node], index[nxt])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == node:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


# ---------------------------------------------------------------- ARCHITECTURE.md


def read_rules(architecture):
    """Crate order, module layers per crate and known exceptions from the `layers` block."""
    text = open(architecture, encoding="utf-8").read()
    m = re.search(r"```layers\n(.*?)```", text, re.S)
    if not m:
        sys.exit(f"{architecture}: no ```layers block (see scripts/check_layers.py)")
    crates, layers, exceptions, never, section = [], defaultdict(list), set(), defaultdict(set), None
    for raw in m.group(1).splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.endswith(":"):
            section = line[:-1].split()
            continue
        if section == ["crates"]:
            crates.append(line.split())
        elif section and section[0] == "modules":
            layers[section[1]].append(line.split())
        elif section and section[0] == "never":
            never[section[1]].update(line.split())
        elif section and section[0] == "exceptions":
            m = re.match(r"(?:(\S+):\s+)?(\S+)\s*->\s*(\S+)$", line)
            if not m:
                sys.exit(f"{architecture}: exception not `[PARENT:] A -> B`: {raw}")
            parent = tuple(m.group(1).split("::")) if m.group(1) else ()
            exceptions.add((section[1], parent, m.group(2), m.group(3)))
        else:
            sys.exit(f"{architecture}: line outside a section in the layers block: {raw}")
    return crates, layers, exceptions, never


# ---------------------------------------------------------------- the checks


def crate_checks(root, crate_order):
    meta = json.loads(subprocess.check_output(
        ["cargo", "metadata", "--format-version", "1", "--no-deps", "--offline"], cwd=root))
    members = {p["name"]: p for p in meta["packages"]}
    rank = {}
    for level, names in enumerate(crate_order):
        for name in names:
            rank[name] = level
    problems, edges = [], []
    for name, pkg in sorted(members.items()):
        if name not in rank:
            problems.append(f"crate {name} is not placed in ARCHITECTURE.md's crate layers")
            continue
        for dep in pkg["dependencies"]:
            other = dep["name"]
            if other not in members or other == name:
                continue
            if dep.get("kind") is None:
                edges.append((name, other))
                if rank.get(other, -1) <= rank[name]:
                    problems.append(f"crate {name} depends on {other}, which is not in a layer below it")
                if not crate_uses(pkg, other):
                    problems.append(f"crate {name} declares {other} but its code never uses it")
    for comp in circles(edges):
        problems.append("crate circle: " + " -> ".join(comp))
    return members, problems


def never_checks(root, never):
    """Outside crates a workspace crate must not reach through its normal dependencies, directly
    or through others (`never CRATE:` sections), each found with the path that reaches it."""
    if not never:
        return []
    args = ["cargo", "metadata", "--format-version", "1"]
    try:  # the registry's cache when it has everything; else (a fresh machine) the network
        out = subprocess.check_output(args + ["--offline"], cwd=root, stderr=subprocess.DEVNULL)
    except subprocess.CalledProcessError:
        out = subprocess.check_output(args, cwd=root)
    meta = json.loads(out)
    names = {p["id"]: p["name"] for p in meta["packages"]}
    deps = {n["id"]: [d["pkg"] for d in n["deps"]
                      if any(k.get("kind") is None for k in d.get("dep_kinds", []))]
            for n in meta["resolve"]["nodes"]}
    members = {names[i]: i for i in meta["workspace_members"]}
    problems = []
    for crate, banned in sorted(never.items()):
        if crate not in members:
            problems.append(f"never {crate}: no such workspace crate")
            continue
        reached, queue = {members[crate]: None}, [members[crate]]
        while queue:
            at = queue.pop(0)
            for d in deps.get(at, []):
                if d not in reached:
                    reached[d] = at
                    queue.append(d)
        for pid in sorted(reached, key=lambda i: names[i]):
            if names[pid] in banned:
                path, at = [], pid
                while at is not None:
                    path.append(names[at])
                    at = reached[at]
                problems.append(f"crate {crate} must never depend on {names[pid]}, but does: "
                                + " -> ".join(reversed(path)))
    return problems


def crate_uses(pkg, other):
    ident = other.replace("-", "_")
    src = os.path.dirname(pkg["manifest_path"])
    for target in pkg["targets"]:
        if "lib" not in target["kind"] and "bin" not in target["kind"]:
            continue
        top = os.path.dirname(target["src_path"])
        for dirpath, _, files in os.walk(top):
            for f in files:
                if f.endswith(".rs") and re.search(r"\b" + ident + r"\b",
                                                    strip_code(open(os.path.join(dirpath, f), encoding="utf-8").read())):
                    return True
    del src
    return False


def module_checks(members, layers, exceptions, graph_of=None):
    problems, used_exceptions = [], set()
    for name, pkg in sorted(members.items()):
        for target in pkg["targets"]:
            if "lib" not in target["kind"] and "bin" not in target["kind"]:
                continue
            crate = Crate(name, target["src_path"])
            levels = crate.arrows()
            if graph_of == name:
                print_graph(crate, levels)
            p, u = check_crate(name, crate, levels, layers.get(name), exceptions)
            problems += p
            used_exceptions |= u
    for exc in sorted(exceptions - used_exceptions):
        crate, parent, a, b = exc
        where = "::".join(parent) + ": " if parent else ""
        problems.append(f"{crate}: known exception `{where}{a} -> {b}` no longer happens: "
                        "remove it from ARCHITECTURE.md")
    return problems


def check_crate(name, crate, levels, crate_layers, exceptions):
    problems, used = [], set()
    rank = {}
    for level, names in enumerate(crate_layers or []):
        for module in names:
            rank[module] = level
    if crate_layers:
        for child in sorted(crate.modules[()].children):
            if child not in rank and child != "tests":
                problems.append(f"{name}: module `{child}` is not placed in ARCHITECTURE.md's layers")
    for parent, arrows in sorted(levels.items()):
        kept = {}
        for (a, b), why in arrows.items():
            key = (name, parent, a, b)
            if key in exceptions:
                used.add(key)
                continue
            kept[(a, b)] = why
            if parent == () and crate_layers and a in rank and b in rank and rank[b] < rank[a]:
                problems.append(f"{name}: `{a}` uses `{b}`, a higher layer\n" + _why(why))
        for comp in circles(kept):
            where = "::".join(parent) or "crate root"
            lines = [f"{name}: circle among the modules of {where}: {' <-> '.join(comp)}"]
            for (a, b), why in sorted(kept.items()):
                if a in comp and b in comp:
                    lines.append(f"  {a} -> {b}:\n" + _why(why, indent="    "))
            problems.append("\n".join(lines))
    return problems, used


def _why(why, indent="  "):
    shown = sorted(why)[:4]
    more = f"\n{indent}… and {len(why) - 4} more" if len(why) > 4 else ""
    return "\n".join(f"{indent}{file}: {path}" for file, path in shown) + more


def print_graph(crate, levels):
    for parent, arrows in sorted(levels.items()):
        where = "::".join(parent) or "crate root"
        print(f"[{crate.name}] {where}")
        for (a, b) in sorted(arrows):
            print(f"  {a} -> {b}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    ap.add_argument("--architecture", help="the file with the layers block (default ROOT/ARCHITECTURE.md)")
    ap.add_argument("--graph", metavar="CRATE", help="also print every arrow among CRATE's modules")
    args = ap.parse_args()
    root = os.path.abspath(args.root)
    os.chdir(root)
    crate_order, layers, exceptions, never = read_rules(args.architecture or os.path.join(root, "ARCHITECTURE.md"))
    members, problems = crate_checks(root, crate_order)
    problems += never_checks(root, never)
    problems += module_checks(members, layers, exceptions, args.graph)
    for p in problems:
        print(p)
    if problems:
        print(f"\n{len(problems)} layering problem(s): dependencies must point down (ARCHITECTURE.md, Layers)")
        return 1
    print(f"layers: {len(members)} crates, every dependency points down, no module circles")
    return 0


if __name__ == "__main__":
    sys.exit(main())
