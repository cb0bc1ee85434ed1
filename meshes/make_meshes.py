"""Regenerate the example meshes of this folder.

    python meshes/make_meshes.py

disc.vtu   flat disc of radius 1 (Delaunay rings, 16 rings): the default scene
strip.vtu  flat strip 4 x 0.25 (64 x 4 cells, alternating diagonals)
"""

from pathlib import Path

import meshio

from shellritz import shapes

HERE = Path(__file__).resolve().parent


def write(mesh, name):
    meshio.write_points_cells(HERE / name, mesh.vertices, [("triangle", mesh.triangles)])
    print(f"{name}: {mesh.n_nodes} nodes, {mesh.n_triangles} triangles")


if __name__ == "__main__":
    write(shapes.disc(16, radius=1.0), "disc.vtu")
    write(shapes.rectangle(64, 4, lx=4.0, ly=0.25, origin=(-2.0, -0.125)), "strip.vtu")
