"""The lightmaps shown in the viewport while a bake runs (live). Imports the base modules and
writeback/."""
