"""Settings: scene.photonlm (scene) and object.photonlm / collection.photonlm (object). Imports the
base modules, export/ (resolution limits) and writeback/ (the preview switch, the last bake's
statistics)."""
