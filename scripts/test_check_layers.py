#!/usr/bin/env python3
"""Tests of scripts/check_layers.py on small workspaces written for each case: it passes on one
whose dependencies point down and fails on each kind of upward or circular dependency.
Run: python3 scripts/test_check_layers.py (needs cargo; reads no registry)."""

import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import unittest

CHECK = os.path.join(os.path.dirname(os.path.abspath(__file__)), "check_layers.py")

LAYERS = """\
```layers
crates:
  app
  base

modules app:
  top
  middle
  bottom
{extra}
```
"""


MADE = []


def tearDownModule():
    for root in MADE:
        shutil.rmtree(root, ignore_errors=True)


def write(root, files):
    for path, text in files.items():
        full = os.path.join(root, path)
        os.makedirs(os.path.dirname(full), exist_ok=True)
        with open(full, "w", encoding="utf-8") as f:
            f.write(textwrap.dedent(text))


def workspace(app_files, extra_layers="", app_deps='base = { path = "../base" }', base_deps=""):
    """A two-crate workspace: `app` (modules top, middle, bottom) over `base`."""
    root = tempfile.mkdtemp(prefix="layers-test-")
    MADE.append(root)
    files = {
        "Cargo.toml": '[workspace]\nresolver = "2"\nmembers = ["app", "base"]\n',
        "app/Cargo.toml": f'[package]\nname = "app"\nversion = "0.1.0"\nedition = "2021"\n\n[dependencies]\n{app_deps}\n',
        "base/Cargo.toml": f'[package]\nname = "base"\nversion = "0.1.0"\nedition = "2021"\n\n[dependencies]\n{base_deps}\n',
        "base/src/lib.rs": "pub fn one() -> u32 { 1 }\n",
        "app/src/lib.rs": "pub mod top;\npub mod middle;\npub mod bottom;\npub fn base_one() -> u32 { base::one() }\n",
        "app/src/top.rs": "use crate::middle::Middle;\npub fn make() -> Middle { Middle }\n",
        "app/src/middle.rs": "use crate::bottom::Bottom;\npub struct Middle;\npub fn low() -> Bottom { Bottom }\n",
        "app/src/bottom.rs": "pub struct Bottom;\n",
        "ARCHITECTURE.md": LAYERS.format(extra=extra_layers),
    }
    files.update(app_files)
    write(root, files)
    return root


def run(root):
    p = subprocess.run([sys.executable, CHECK, "--root", root], capture_output=True, text=True)
    return p.returncode, p.stdout + p.stderr


class CheckLayers(unittest.TestCase):
    def assert_fails(self, root, *expected):
        code, out = run(root)
        self.assertEqual(code, 1, out)
        for e in expected:
            self.assertIn(e, out)

    def test_dependencies_pointing_down_pass(self):
        code, out = run(workspace({}))
        self.assertEqual(code, 0, out)

    def test_an_upward_use_fails(self):
        root = workspace({"app/src/bottom.rs": "use crate::top::make;\npub struct Bottom;\n"})
        self.assert_fails(root, "`bottom` uses `top`, a higher layer", "app/src/bottom.rs: top::make")

    def test_an_upward_path_inside_code_fails(self):
        root = workspace({"app/src/middle.rs": """\
            pub struct Middle;
            pub fn low() -> u32 { let _ = crate::top::make(); 0 }
            """})
        self.assert_fails(root, "`middle` uses `top`, a higher layer")

    def test_a_circle_between_siblings_fails_and_names_both_ways(self):
        root = workspace({
            "app/src/lib.rs": "pub mod top;\npub mod middle;\npub mod bottom;\npub mod inner;\n",
            "app/src/inner/mod.rs": "mod a;\nmod b;\n",
            "app/src/inner/a.rs": "use super::b::B;\npub struct A(pub Option<Box<B>>);\n",
            "app/src/inner/b.rs": "pub struct B(pub Option<Box<super::a::A>>);\n",
        }, extra_layers="  inner\n")
        self.assert_fails(root, "circle among the modules of inner: a <-> b", "a -> b:", "b -> a:")

    def test_a_re_export_counts_where_the_item_is_defined(self):
        # `bottom` names `crate::Thing`, which lib.rs re-exports from `top`: an upward arrow.
        root = workspace({
            "app/src/lib.rs": "pub mod top;\npub mod middle;\npub mod bottom;\npub use top::Thing;\n",
            "app/src/top.rs": "pub struct Thing;\n",
            "app/src/bottom.rs": "pub struct Bottom(pub Option<crate::Thing>);\n",
        })
        self.assert_fails(root, "`bottom` uses `top`, a higher layer")

    def test_a_parent_calling_a_child_that_uses_the_parent_is_a_circle(self):
        # Called by path, or through a name the parent re-exports.
        for parent in ("mod a;\npub struct Shared;\npub fn go() { a::run() }\n",
                       "mod a;\npub use a::run;\npub struct Shared;\npub fn go() { run() }\n"):
            with self.subTest(parent=parent):
                root = workspace({
                    "app/src/lib.rs": "pub mod top;\npub mod middle;\npub mod bottom;\npub mod inner;\n",
                    "app/src/inner/mod.rs": parent,
                    "app/src/inner/a.rs": "use super::Shared;\npub fn run() { let _ = Shared; }\n",
                }, extra_layers="  inner\n")
                self.assert_fails(root, "circle among the modules of inner: (own) <-> a")

    def test_a_known_exception_allows_an_arrow_and_a_stale_one_fails(self):
        upward = {"app/src/bottom.rs": "use crate::top::make;\npub struct Bottom;\n"}
        allowed = "\nexceptions app:\n  bottom -> top\n"
        code, out = run(workspace(upward, extra_layers=allowed))
        self.assertEqual(code, 0, out)
        self.assert_fails(workspace({}, extra_layers=allowed), "`bottom -> top` no longer happens")

    def test_comments_and_strings_are_not_imports(self):
        root = workspace({"app/src/bottom.rs": """\
            // use crate::top::make;
            /// See [`crate::top::make`].
            pub struct Bottom;
            pub const TEXT: &str = "crate::top::make";
            """})
        code, out = run(root)
        self.assertEqual(code, 0, out)

    def test_an_unplaced_module_fails(self):
        root = workspace({
            "app/src/lib.rs": "pub mod top;\npub mod middle;\npub mod bottom;\npub mod stray;\n",
            "app/src/stray.rs": "pub struct Stray;\n",
        })
        self.assert_fails(root, "module `stray` is not placed")

    def test_an_upward_crate_dependency_fails(self):
        root = workspace({"base/src/lib.rs": "pub fn one() -> u32 { 1 }\n"},
                         app_deps="", base_deps='app = { path = "../app" }')
        self.assert_fails(root, "crate base depends on app, which is not in a layer below it")

    def test_a_crate_reaching_a_never_crate_fails_naming_the_path(self):
        netio = {
            "netio/Cargo.toml": '[package]\nname = "netio"\nversion = "0.1.0"\nedition = "2021"\n',
            "netio/src/lib.rs": "pub fn send() {}\n",
            "base/src/lib.rs": "pub fn one() -> u32 { netio::send(); 1 }\n",
        }
        deps = 'netio = { path = "../netio" }'
        root = workspace(netio, "never app:\n  netio\n", base_deps=deps)
        with open(os.path.join(root, "Cargo.toml"), "a", encoding="utf-8") as f:
            f.write('exclude = ["netio"]\n')
        self.assert_fails(root, "crate app must never depend on netio, but does: app -> base -> netio")
        root = workspace(netio, "never base:\n  other\n", base_deps=deps)
        with open(os.path.join(root, "Cargo.toml"), "a", encoding="utf-8") as f:
            f.write('exclude = ["netio"]\n')
        code, out = run(root)
        self.assertEqual(code, 0, out)

    def test_a_declared_but_unused_crate_fails(self):
        root = workspace({"app/src/lib.rs": "pub mod top;\npub mod middle;\npub mod bottom;\n"})
        self.assert_fails(root, "crate app declares base but its code never uses it")


if __name__ == "__main__":
    unittest.main()
