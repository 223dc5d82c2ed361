"""rigcast Live Link: stream poses from a rigcast server onto Blender armatures.

View3D > Sidebar (N) > rigcast. Works in Blender 3.4+ (legacy add-on, `bl_info`) and 4.2+
(extension, `blender_manifest.toml`). Needs no third-party Python module.
"""

bl_info = {
    "name": "rigcast Live Link",
    "author": "rigcast contributors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > rigcast",
    "description": "Live pose stream from a rigcast server (WebSocket) or any VMC performer",
    "category": "Animation",
}

try:
    import bpy  # noqa: F401
except ImportError:
    # Imported outside Blender (unit tests, tools): only the bpy-free modules are usable.
    bpy = None

if bpy is not None:
    if "ui" in locals():
        import importlib

        for _module in (convert, wire, wsclient, vmc, session, record, livelink, ui):  # noqa: F821
            importlib.reload(_module)
    else:
        from . import convert, livelink, record, session, ui, vmc, wire, wsclient


def register():
    ui.register()


def unregister():
    ui.unregister()
