"""The scene: the in-memory model (:mod:`.model`), materials, textures, meshes and the file loaders.
"""
