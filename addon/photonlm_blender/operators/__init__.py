"""Operators: bake and remove the preview (bake), L-systems (lsystem), File > Export > PhotonLM scene
(export_scene_file), File > Import > PhotonLM bake folder (import_folder). Import everything
below them; the UI imports them."""
