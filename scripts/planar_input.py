"""Writes a copy of a converted BlazePose model (landmarks or detector) that takes its input
channels first (batch, 3, height, width) instead of channels last.

Usage: planar_input.py IN.onnx OUT.onnx

The TFLite models take channels last; tf2onnx keeps that input and opens the graph with a
zero Pad of the image's edges and a Transpose to channels first, then the first convolution.
ONNX Runtime runs both as nodes of their own over the whole input (about 0.2 ms of the lite
landmark model's 6.9 a run, one thread). Here the input is declared channels first (rigcast's
crop warp writes it so), the Transpose goes, and the Pad becomes the convolution's own
padding: a convolution pads with zeros as the Pad did. ONNX Runtime's outputs are the same
to the bit (checked by rigcast's footage judge on every clip). setup-vision.sh makes such a
copy of each pruned landmark model and of the detector, beside the originals.
"""
import sys

import onnx
from onnx import numpy_helper


def consumers_of(graph, name):
    return [n for n in graph.node if name in n.input]


def make_planar(model):
    """Rewrites `model` in place: input channels first, the edge Pad folded into the first
    convolution, the Transpose dropped. Exits on a graph not shaped as expected."""
    graph = model.graph
    image = graph.input[0]
    inits = {i.name: i for i in graph.initializer}

    def consumers(name):
        return consumers_of(graph, name)

    def expect(nodes, op):
        if len(nodes) != 1 or nodes[0].op_type != op:
            sys.exit(f"expected one {op} after the input, found {[n.op_type for n in nodes]}: "
                     "not the converted model this step knows")
        return nodes[0]

    pad = expect(consumers(image.name), "Pad")
    transpose = expect(consumers(pad.output[0]), "Transpose")
    convs = consumers(transpose.output[0])
    if not convs or any(c.op_type != "Conv" for c in convs):
        sys.exit("the transposed input does not feed convolutions only")
    if list(next(a.ints for a in transpose.attribute if a.name == "perm")) != [0, 3, 1, 2]:
        sys.exit("the input transpose is not channels last to channels first")
    mode = next((a.s for a in pad.attribute if a.name == "mode"), b"constant")
    value = (numpy_helper.to_array(inits[pad.input[2]]).item()
             if len(pad.input) > 2 and pad.input[2] else 0.0)
    pads = numpy_helper.to_array(inits[pad.input[1]]).tolist()
    # Channels-last pads: [n, h, w, c] begins, then ends. Only the image's edges, with zeros.
    if mode != b"constant" or value != 0.0 or pads[0] or pads[3] or pads[4] or pads[7]:
        sys.exit(f"the input Pad is not zeros at the image's edges ({mode}, {value}, {pads})")
    edges = [pads[1], pads[2], pads[5], pads[6]]  # Conv's: h, w begins, then ends
    for conv in convs:
        attrs = {a.name: a for a in conv.attribute}
        if "auto_pad" in attrs and attrs["auto_pad"].s not in (b"NOTSET", b"VALID"):
            sys.exit(f"{conv.name}: auto_pad {attrs['auto_pad'].s}")
        if "pads" in attrs:
            attrs["pads"].ints[:] = [a + b for a, b in zip(attrs["pads"].ints, edges)]
        else:
            conv.attribute.append(onnx.helper.make_attribute("pads", edges))
        conv.input[0] = image.name
    graph.node.remove(pad)
    graph.node.remove(transpose)
    for name in pad.input[1:]:
        if name in inits and not consumers(name):
            graph.initializer.remove(inits[name])
    dims = image.type.tensor_type.shape.dim
    height, width, channels = (dims[i].dim_value for i in (1, 2, 3))
    dims[1].dim_value, dims[2].dim_value, dims[3].dim_value = channels, height, width


if __name__ == "__main__":
    src, dst = sys.argv[1], sys.argv[2]
    model = onnx.load(src)
    make_planar(model)
    del model.graph.value_info[:]
    onnx.checker.check_model(model)
    onnx.save(model, dst)
    print(f"{src}: input channels first")
