"""Example meshes shipped with shellritz (package ``shellritz.meshes``);
``make_meshes.py`` regenerates them."""
