"""The light BVH's node record, which abi registers among the shared structs (``LightNode``):
render/light_tree.py builds the nodes, cl/render/light_tree.h walks them.

A node (64 bytes): the sphere around the box of its lights (centre; radius: half the box's
diagonal), the cone of their emission (unit axis; cos_o and sin_o: the spread of their normals;
cos_e: how far past a normal they emit), their summed power phi, two_sided (1 when any of them
emits from both sides), and child: for an inner node the index of its second child (the first
follows it), for a leaf -1 - the row of its light (child < 0 marks a leaf).  Light.trail holds the
root-to-leaf path of each light in the tree (bit d set: the second child at depth d), -1 for a
light not in it."""
import numpy as np

LIGHT_NODE = np.dtype([("centre", np.float32, 3), ("child", np.int32), ("axis", np.float32, 3),
                       ("two_sided", np.int32), ("radius", np.float32), ("phi", np.float32), ("cos_o", np.float32),
                       ("sin_o", np.float32), ("cos_e", np.float32), ("pad", np.int32, 3)])
assert LIGHT_NODE.itemsize == 64
