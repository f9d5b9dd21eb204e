"""The light BVH's node record (render/light_tree.py builds it, cl/render/light_tree.h walks it),
registered in abi.STRUCTS and abi.DEFINES as every shared struct is (abi imports this module last).

A node (64 bytes): the sphere around the box of its lights (centre; radius: half the box's
diagonal), the cone of their emission (unit axis; cos_o and sin_o: the spread of their normals;
cos_e: how far past a normal they emit), their summed power phi; flags LIGHT_NODE_LEAF (child is
then the light's row) and LIGHT_NODE_TWO_SIDED.  An inner node's first child follows it; child is
the second's index.  Light.trail: bit d set where the path to the light's leaf takes the second
child at depth d."""
import numpy as np

from .abi import STRUCTS, define

LIGHT_NODE_LEAF = define("LIGHT_NODE_LEAF", 1)
LIGHT_NODE_TWO_SIDED = define("LIGHT_NODE_TWO_SIDED", 2)
LIGHT_NODE = np.dtype([("centre", np.float32, 3), ("child", np.int32), ("axis", np.float32, 3), ("flags", np.int32),
                       ("radius", np.float32), ("phi", np.float32), ("cos_o", np.float32), ("sin_o", np.float32),
                       ("cos_e", np.float32), ("pad", np.int32, 3)])
assert LIGHT_NODE.itemsize == 64
STRUCTS["LightNode"] = LIGHT_NODE
