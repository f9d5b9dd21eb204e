"""The scene: the in-memory model (:mod:`.model`), the material types (:mod:`.materials`), textures,
meshes and the scene-file loaders (:mod:`.loaders`).
"""
