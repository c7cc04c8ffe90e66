"""A bake: run here (job: export, engine on a worker thread, write-back), sent to batch machines as a
scene file (scene_file), or brought back from their bake folder (folder). Imports the base modules,
export/, uv/ and writeback/."""
