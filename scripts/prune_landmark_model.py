"""Writes a copy of a BlazePose landmark model that computes only what rigcast reads.

Usage: prune_landmark_model.py IN.onnx OUT.onnx

The converted model has five outputs: landmarks (Identity), pose presence (Identity_1),
segmentation mask (Identity_2, 256x256), heatmaps (Identity_3, 64x64x39) and world landmarks
(Identity_4). ONNX Runtime runs every node of a graph whatever outputs a caller asks for, and
the mask and heatmap decoders (upsampling convolutions at high resolution) are about half the
model's work. Keeping only the subgraph behind the outputs rigcast uses gives the same numbers
(the kept nodes and weights are untouched) in about half the time. The heatmaps are kept (since
the setup's derivation 3): rigcast refines the body's landmarks from them, as MediaPipe does,
for about a tenth more work a run than the three other outputs alone.

The copy's batch dimension is left open (the converted model fixes it at 1, but its reshapes
already take any batch), so rigcast can run the crops of every tracked person in one call.
"""
import sys

import onnx
import onnx.utils
from onnx import numpy_helper

KEEP = ["Identity", "Identity_1", "Identity_4", "Identity_3"]
HEATMAPS = "Identity_3"
# The landmarks whose heatmaps rigcast reads (model.rs's REFINED), and how many there are.
REFINED = range(11, 33)
LANDMARKS = 39


def keep_refined_heatmaps(graph):
    """Slices the heatmap head's last convolution to the REFINED landmarks' channels."""
    producer = {o: n for n in graph.node for o in n.output}
    transpose = producer[HEATMAPS]
    conv = producer.get(transpose.input[0])
    inits = {i.name: i for i in graph.initializer}
    if (transpose.op_type != "Transpose" or conv is None or conv.op_type != "Conv"
            or len(conv.input) != 3):
        sys.exit(f"{HEATMAPS} is not a convolution then a transpose; not the expected model")
    for name in conv.input[1:]:
        value = numpy_helper.to_array(inits[name])
        if value.shape[0] != LANDMARKS:
            sys.exit(f"{name}: {value.shape[0]} output channels, expected {LANDMARKS}")
        if sum(1 for n in graph.node if name in n.input) != 1:
            sys.exit(f"{name} is shared with other nodes; slicing it would change them")
        inits[name].CopyFrom(numpy_helper.from_array(value[REFINED.start:REFINED.stop], name))
    out = next(o for o in graph.output if o.name == HEATMAPS)
    out.type.tensor_type.shape.dim[3].dim_value = len(REFINED)


src, dst = sys.argv[1], sys.argv[2]
model = onnx.load(src)
names = [o.name for o in model.graph.output]
missing = [n for n in KEEP if n not in names]
if missing:
    sys.exit(f"{src}: no output(s) {missing} (has {names}); not a BlazePose landmark model?")
inputs = [i.name for i in model.graph.input]
pruned = onnx.utils.Extractor(model).extract_model(inputs, KEEP)
keep_refined_heatmaps(pruned.graph)
for value in list(pruned.graph.input) + list(pruned.graph.output):
    value.type.tensor_type.shape.dim[0].dim_param = "batch"
# Inferred intermediate shapes still say batch 1; the runtime infers them again.
del pruned.graph.value_info[:]
onnx.checker.check_model(pruned)
onnx.save(pruned, dst)
print(f"{src}: {len(model.graph.node)} -> {len(pruned.graph.node)} nodes")
