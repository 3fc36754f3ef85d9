"""Low-level helpers below the plugins, which plugins, trainers and the experiment layer all use:
where work units run (`executors`), the run-scoped cache folder (`cache`), files that component
settings name (`inputs`) and the layout of scenario ids (`heldout`).

Nothing here imports a plugin or `ata.experiment`; `ata.core` is the only layer below."""
