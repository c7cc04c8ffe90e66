"""Render Properties > PhotonLM Lightmaps (panel). Reads state; changes nothing itself."""
