"""Recording live poses into Actions, on every Blender the add-on supports.

Blender 4.4 made Actions layered ("slotted"): F-curves live in a channelbag of a keyframe strip
on a layer, per slot, and the object is bound to one slot of its Action. Blender 5.0 removed the
old `Action.fcurves` list. Blender 3.4-4.3 only have that old list. `Channels` hides the two
behind one "give me the F-curve for (bone, property, index)" call; `Take` does the timing.
"""

import bpy


def has_layered_actions():
    """True on Blender 4.4+, where Actions have layers, strips and slots."""
    # RNA properties are not Python class attributes: ask the RNA definition.
    return "layers" in bpy.types.Action.bl_rna.properties and "slots" in bpy.types.Action.bl_rna.properties


class LegacyChannels:
    """Blender < 4.4: F-curves straight on the Action, grouped by `action_group`."""

    def __init__(self, action, obj):
        self.action = action

    def new_fcurve(self, data_path, index, group):
        return self.action.fcurves.new(data_path, index=index, action_group=group)

    def bind(self, obj):
        obj.animation_data.action = self.action


class LayeredChannels:
    """Blender 4.4+: one layer, one keyframe strip, one slot for this armature."""

    def __init__(self, action, obj):
        self.action = action
        # Slots are per animated ID; naming it after the armature keeps several takes readable
        # in the Action editor and lets Blender bind it by name if the user reassigns it.
        self.slot = action.slots.new(id_type="OBJECT", name=obj.name)
        layer = action.layers.new("rigcast")
        strip = layer.strips.new(type="KEYFRAME")
        self.channelbag = strip.channelbag(self.slot, ensure=True)
        self.groups = {}

    def _group(self, name):
        group = self.groups.get(name)
        if group is None:
            group = self.channelbag.groups.new(name)
            self.groups[name] = group
        return group

    def new_fcurve(self, data_path, index, group):
        # 5.0 takes group_name in new(); 4.4/4.5 do not, so group explicitly on every version.
        curve = self.channelbag.fcurves.new(data_path, index=index)
        curve.group = self._group(group)
        return curve

    def bind(self, obj):
        obj.animation_data.action = self.action
        obj.animation_data.action_slot = self.slot


class Take:
    """One armature's recording into a new Action, assigned only when recording stops.

    While recording, the Action is kept off the armature: an assigned Action would be evaluated
    by the depsgraph at the scene's current frame and fight the live pose. Keys go straight to
    F-curves (quaternion w, x, y, z grouped by bone) at the scene frame the capture time falls
    on; network jitter therefore does not warp the take, and the scene's frame rate is used,
    never changed.
    """

    def __init__(self, obj, scene, first_capture_nanos):
        self.obj = obj
        self.fps = scene.render.fps / scene.render.fps_base
        self.origin_nanos = first_capture_nanos
        self.origin_frame = scene.frame_current
        self.last_frame = None
        self.action = bpy.data.actions.new("rigcast_%s" % obj.name)
        channels = LayeredChannels if has_layered_actions() else LegacyChannels
        try:
            self.channels = channels(self.action, obj)
        except Exception:
            # Leave no empty Action behind when this Blender refuses the layout.
            bpy.data.actions.remove(self.action)
            raise
        self.curves = {}

    def _curve(self, bone_name, prop, index):
        key = (bone_name, prop, index)
        curve = self.curves.get(key)
        if curve is None:
            path = 'pose.bones["%s"].%s' % (bpy.utils.escape_identifier(bone_name), prop)
            curve = self.channels.new_fcurve(path, index, bone_name)
            self.curves[key] = curve
        return curve

    def add(self, binding, capture_nanos):
        """Keys the armature's current pose; returns the scene frame keyed, or None."""
        # The user may delete the Action mid-take (Outliner, Python). The ID reference then
        # raises ReferenceError, but the F-curves cached from it would dangle and keying them
        # crashes Blender 4.x/5.x: touch the ID first, so the take stops with an error instead.
        self.action.name  # noqa: B018 (raises ReferenceError once removed)
        frame = self.origin_frame + int(round((capture_nanos - self.origin_nanos) * 1e-9 * self.fps))
        if self.last_frame is not None and frame <= self.last_frame:
            return None
        self.last_frame = frame
        for entry in binding.bones:
            pose_bone = entry.pose_bone
            q = pose_bone.rotation_quaternion
            for index in range(4):
                self._curve(pose_bone.name, "rotation_quaternion", index).keyframe_points.insert(
                    frame, q[index], options={"FAST"}
                )
            if entry.is_root or getattr(entry, "slot", None) is not None:
                location = pose_bone.location
                for index in range(3):
                    self._curve(pose_bone.name, "location", index).keyframe_points.insert(
                        frame, location[index], options={"FAST"}
                    )
        return frame

    def finish(self):
        """Assigns the Action (and its slot); an empty take is removed rather than left over."""
        if not self.curves:
            bpy.data.actions.remove(self.action)
            return None
        for curve in self.curves.values():
            curve.update()
        if self.obj.animation_data is None:
            self.obj.animation_data_create()
        self.channels.bind(self.obj)
        return self.action

