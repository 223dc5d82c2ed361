#!/usr/bin/env python3
"""Builds the installable add-on zip: `python3 clients/blender/build_zip.py [--out PATH]`.

Default output: dist/rigcast_livelink.zip at the repository root. The zip holds one folder,
rigcast_livelink/, with `bl_info` (Blender 3.4+: Edit > Preferences > Add-ons > Install) and
`blender_manifest.toml` (Blender 4.2+: Get Extensions > Install from Disk).
"""

import argparse
import os
import sys
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = "rigcast_livelink"


def build(out_path):
    source = os.path.join(HERE, PACKAGE)
    os.makedirs(os.path.dirname(os.path.abspath(out_path)), exist_ok=True)
    names = sorted(
        n for n in os.listdir(source) if n.endswith((".py", ".toml")) and not n.startswith(".")
    )
    with zipfile.ZipFile(out_path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name in names:
            # Fixed timestamps keep the zip byte-identical across builds.
            info = zipfile.ZipInfo("%s/%s" % (PACKAGE, name), date_time=(2024, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            with open(os.path.join(source, name), "rb") as handle:
                archive.writestr(info, handle.read())
    return out_path


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__)
    default = os.path.join(HERE, "..", "..", "dist", PACKAGE + ".zip")
    parser.add_argument("--out", default=default, help="output zip path")
    args = parser.parse_args(argv)
    path = build(args.out)
    print(os.path.normpath(path))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
