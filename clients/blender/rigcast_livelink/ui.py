"""Properties, operators and the 3D-view sidebar panel (View3D > Sidebar > rigcast)."""

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from . import livelink
from .session import DEFAULT_ADDRESS, parse_address


def _is_armature(_self, obj):
    return obj.type == "ARMATURE"


def _on_color_mode(self, _context):
    livelink.apply_mapping_colors(self, livelink.runtime, self.color_mode)


def _on_mapping_row(self, _context):
    if 0 <= self.mapping_index < len(self.mapping_items):
        self.override_source = self.mapping_items[self.mapping_index].source


def _on_subject_row(self, _context):
    if 0 <= self.subject_index < len(self.subjects):
        item = self.subjects[self.subject_index]
        if item.kind == "target" and self.mapping_subject != item.subject_id:
            self.mapping_subject = item.subject_id
            livelink.refresh_mapping_ui(self, livelink.runtime)


class RIGCAST_PG_subject(bpy.types.PropertyGroup):
    subject_id: IntProperty(name="Id")
    kind: StringProperty(name="Kind")
    num_bones: IntProperty(name="Bones")
    source_id: IntProperty(name="Source", default=-1)
    armature: PointerProperty(name="Armature", type=bpy.types.Object, poll=_is_armature)
    live: BoolProperty(name="Live", default=True, description="Apply incoming frames to the armature")


class RIGCAST_PG_mapping(bpy.types.PropertyGroup):
    target: StringProperty(name="Target bone")
    source: StringProperty(name="Source bone")
    score: FloatProperty(name="Score")
    confidence: FloatProperty(name="Confidence", default=1.0)
    flagged: StringProperty(name="Check", description="Why the mapper asks to check this bone; empty when it does not")
    color_gradient: FloatVectorProperty(name="Gradient colour", subtype="COLOR", size=3, min=0, max=1)
    color_random: FloatVectorProperty(name="Random colour", subtype="COLOR", size=3, min=0, max=1)


class RIGCAST_PG_bone_name(bpy.types.PropertyGroup):
    pass


class RIGCAST_PG_settings(bpy.types.PropertyGroup):
    address: StringProperty(
        name="Server", default=DEFAULT_ADDRESS, description="rigcast server address, host:port"
    )
    token: StringProperty(
        name="Token",
        default="",
        subtype="PASSWORD",
        description=(
            "The server's control token (`rigcast token show` prints it). Needed to override "
            "mappings, and to connect to a server listening beyond loopback; empty = view only"
        ),
    )
    transport: EnumProperty(
        name="Transport",
        items=[
            ("WEBSOCKET", "WebSocket", "rigcast stream: skeletons, mappings and pose frames"),
            ("VMC", "VMC/OSC", "Receive VMC (OSC over UDP) from any VMC performer"),
        ],
        default="WEBSOCKET",
    )
    vmc_port: IntProperty(name="VMC port", default=39539, min=1, max=65535)
    vmc_armature: PointerProperty(name="VMC armature", type=bpy.types.Object, poll=_is_armature)
    auto_reconnect: BoolProperty(name="Auto-reconnect", default=True)
    subjects: CollectionProperty(type=RIGCAST_PG_subject)
    subject_index: IntProperty(update=_on_subject_row)
    mapping_subject: IntProperty(default=-1)
    mapping_items: CollectionProperty(type=RIGCAST_PG_mapping)
    mapping_index: IntProperty(update=_on_mapping_row)
    source_bones: CollectionProperty(type=RIGCAST_PG_bone_name)
    override_source: StringProperty(name="Source bone", description="Source bone for the selected target bone; empty = unmapped")
    color_mode: EnumProperty(
        name="Bone colours",
        items=[
            ("NONE", "None", "Leave bone colours alone"),
            ("GRADIENT", "Gradient", "Colour by position in the hierarchy (mapped pairs share colours)"),
            ("RANDOM", "Random", "Distinct random colour per mapped pair"),
        ],
        default="NONE",
        update=_on_color_mode,
    )


# -- operators -----------------------------------------------------------------------------


def _refused(operator, message):
    """Reports `message` as the operator's error and cancels it."""
    operator.report({"ERROR"}, message)
    return {"CANCELLED"}


class RIGCAST_OT_connect(bpy.types.Operator):
    """Connect to the rigcast server (or start listening for VMC)"""
    bl_idname, bl_label = "rigcast.connect", "Connect"

    def execute(self, context):
        try:
            _connect(context.scene.rigcast)
        except (ValueError, OSError) as exc:
            return _refused(self, str(exc))
        return {"FINISHED"}


def _connect(settings):
    """Connects as `settings` say; a malformed server address raises before anything opens."""
    if settings.transport == "WEBSOCKET":
        parse_address(settings.address)
    livelink.runtime.connect(settings)


class RIGCAST_OT_disconnect(bpy.types.Operator):
    bl_idname, bl_label = "rigcast.disconnect", "Disconnect"

    def execute(self, context):
        livelink.runtime.disconnect()
        return {"FINISHED"}


class RIGCAST_OT_create_armature(bpy.types.Operator):
    """Build an armature whose rest pose is the subject's skeleton and assign it"""
    bl_idname, bl_label = "rigcast.create_armature", "Create armature from subject"
    bl_options = {"REGISTER", "UNDO"}

    subject_id: IntProperty(name="Subject", default=-1)

    def execute(self, context):
        settings = context.scene.rigcast
        subject_id = self.subject_id
        picked = _selected(settings.subjects, settings.subject_index)
        if subject_id < 0 and picked is not None:
            subject_id = picked.subject_id
        skeleton = livelink.runtime.skeletons.get(subject_id)
        if skeleton is None:
            return _refused(self, "no skeleton received yet for subject %d" % subject_id)
        name = "rigcast_%s" % skeleton.get("name", subject_id)
        obj = livelink.create_armature(context, skeleton, name)
        for item in settings.subjects:
            if item.subject_id == subject_id:
                item.armature = obj
        # The foot-lock state arrives only on changes: show the latest one at once.
        livelink.runtime.show_footplants(settings, subject_id)
        return {"FINISHED"}


class RIGCAST_OT_set_override(bpy.types.Operator):
    """Map the selected target bone to the chosen source bone (empty = unmapped) on the server"""
    bl_idname, bl_label = "rigcast.set_override", "Send override"

    def execute(self, context):
        settings = context.scene.rigcast
        row = _selected(settings.mapping_items, settings.mapping_index)
        if row is None:
            return _refused(self, "pick a row of the mapping first")
        target = row.target
        source = settings.override_source or None
        session = livelink.runtime.session
        message = {"type": "set_mapping", "subject": settings.mapping_subject, "overrides": {target: source}}
        if session is None or not session.send(message):
            return _refused(self, "not connected to a rigcast server")
        return {"FINISHED"}


class RIGCAST_OT_record(bpy.types.Operator):
    """Start/stop recording incoming poses to Actions at the scene frame rate"""
    bl_idname, bl_label = "rigcast.record", "Record"

    def execute(self, context):
        runtime = livelink.runtime
        if runtime.recording:
            runtime.stop_recording()
        else:
            runtime.start_recording(context.scene)
        return {"FINISHED"}


# -- UI ------------------------------------------------------------------------------------


class RIGCAST_UL_subjects(bpy.types.UIList):
    def draw_item(self, _context, layout, _data, item, _icon, _active_data, _active_prop, _index=0):
        row = layout.row(align=True)
        stats = livelink.runtime.stats.get(item.subject_id)
        icon = "ARMATURE_DATA" if item.kind == "target" else "OUTLINER_OB_ARMATURE"
        row.prop(item, "live", text="")
        row.label(text="%d %s" % (item.subject_id, item.name), icon=icon)
        row.prop(item, "armature", text="")
        if stats is not None:
            row.label(text="%.0f fps" % stats.fps(_monotonic()))


class RIGCAST_UL_mapping(bpy.types.UIList):
    def draw_item(self, context, layout, _data, item, _icon, _active_data, _active_prop, _index=0):
        settings = context.scene.rigcast
        row = layout.row(align=True)
        sub = row.row()
        sub.ui_units_x = 1
        sub.prop(item, "color_random" if settings.color_mode == "RANDOM" else "color_gradient", text="")
        icon, confidence = mapping_row_marks(item)
        row.label(text=item.target, icon=icon)
        row.label(text=item.source or "(unmapped)")
        row.label(text=confidence)


def mapping_row_marks(item):
    """(icon, confidence text) of a mapping row: a flagged bone wears the warning icon, for the
    user to check and fix with an override (pick the row, pick a bone, Send)."""
    return ("ERROR" if item.flagged else "NONE", "%.2f" % item.confidence)


def _selected(items, index):
    """The list row at `index`, or None when nothing (valid) is selected."""
    return items[index] if 0 <= index < len(items) else None


def _monotonic():
    import time

    return time.monotonic()


class RIGCAST_PT_panel(bpy.types.Panel):
    bl_label = "rigcast Live Link"
    bl_idname = "RIGCAST_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "rigcast"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.rigcast
        runtime = livelink.runtime
        connected = runtime.session is not None or runtime.vmc is not None

        box = layout.box()
        box.prop(settings, "transport", expand=True)
        if settings.transport == "VMC":
            box.prop(settings, "vmc_port")
            box.prop(settings, "vmc_armature")
        else:
            box.prop(settings, "address")
            box.prop(settings, "token")
            box.prop(settings, "auto_reconnect")
        row = box.row()
        if connected:
            row.operator("rigcast.disconnect", icon="UNLINKED")
        else:
            row.operator("rigcast.connect", icon="LINKED")
        box.label(text=runtime.status_text(), icon="INFO")
        session = runtime.session
        if session is not None and session.error:
            box.label(text=session.error, icon="ERROR")
        if runtime.last_error:
            box.label(text=runtime.last_error, icon="ERROR")

        if settings.transport == "WEBSOCKET":
            layout.label(text="Subjects")
            layout.template_list("RIGCAST_UL_subjects", "", settings, "subjects", settings, "subject_index", rows=3)
            layout.operator("rigcast.create_armature", icon="ARMATURE_DATA")
            if 0 <= settings.subject_index < len(settings.subjects):
                stats = runtime.stats.get(settings.subjects[settings.subject_index].subject_id)
                if stats is not None:
                    col = layout.column(align=True)
                    col.label(text="%.0f frames/s   latency %.1f ms" % (stats.fps(_monotonic()), stats.latency_ms))
                    missed = session.num_frames_missed if session else 0
                    skipped = session.num_frames_skipped if session else 0
                    col.label(text="missed %d (server)   skipped %d (display)" % (missed, skipped))
                plants = runtime.footplants.get(settings.subjects[settings.subject_index].subject_id)
                if plants is not None and plants.get("feet"):
                    # The foot lock's state; also on the armature as custom properties.
                    feet = "   ".join(
                        "%s %s" % (f.get("bone", "?"), "planted" if f.get("planted") else "free")
                        for f in plants["feet"]
                        if isinstance(f, dict)
                    )
                    layout.label(text="feet: " + feet, icon="INFO")

            layout.label(text="Mapping (pick a row, pick a bone)")
            flagged = [item for item in settings.mapping_items if item.flagged]
            if flagged:
                layout.label(text="%d bone(s) to check (marked); pick one to see why" % len(flagged), icon="ERROR")
                if 0 <= settings.mapping_index < len(settings.mapping_items):
                    picked = settings.mapping_items[settings.mapping_index]
                    if picked.flagged:
                        layout.label(text="%s: %s" % (picked.target, picked.flagged))
            layout.template_list("RIGCAST_UL_mapping", "", settings, "mapping_items", settings, "mapping_index", rows=5)
            row = layout.row(align=True)
            row.prop_search(settings, "override_source", settings, "source_bones", text="")
            row.operator("rigcast.set_override", text="Send", icon="EXPORT")
            layout.prop(settings, "color_mode", expand=True)

        row = layout.row()
        row.operator(
            "rigcast.record",
            text="Stop recording" if runtime.recording else "Record",
            icon="PAUSE" if runtime.recording else "REC",
            depress=runtime.recording,
        )


classes = (
    RIGCAST_PG_subject,
    RIGCAST_PG_mapping,
    RIGCAST_PG_bone_name,
    RIGCAST_PG_settings,
    RIGCAST_OT_connect,
    RIGCAST_OT_disconnect,
    RIGCAST_OT_create_armature,
    RIGCAST_OT_set_override,
    RIGCAST_OT_record,
    RIGCAST_UL_subjects,
    RIGCAST_UL_mapping,
    RIGCAST_PT_panel,
)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.rigcast = PointerProperty(type=RIGCAST_PG_settings)


def unregister():
    livelink.runtime.disconnect()
    livelink.stop_timer()
    del bpy.types.Scene.rigcast
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
