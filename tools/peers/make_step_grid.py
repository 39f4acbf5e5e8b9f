#!/usr/bin/env python3
"""Write the grid-convention probe's OpenVDB file: a slab of density 1.

    /usr/bin/python3 tools/peers/make_step_grid.py OUT.vdb

Grid `density`, voxel size 1, index = world: value 1 at the index points x in [-8, -1],
y in [-20, 19], z in [-16, 15], background 0. Under the OpenVDB convention (voxel i is the sample
at index point i, trilinear interpolation) the field is 1 for x in [-8, -1], falls linearly to 0
over x in [-1, 0] and over x in [-9, -8], and is 0 beyond. tools/peers/grid_convention_probe.py
renders it with every renderer and compares their transmittance profiles with that field.
"""

import sys

import numpy as np
import pyopenvdb as vdb

a = np.zeros((16, 40, 32), dtype=np.float32)  # x in [-8, 8), y in [-20, 20), z in [-16, 16)
a[:8] = 1.0
g = vdb.FloatGrid(0.0)
g.name = "density"
g.copyFromArray(a, ijk=(-8, -20, -16), tolerance=0.0)
g.transform = vdb.createLinearTransform(1.0)
vdb.write(sys.argv[1], grids=[g])
