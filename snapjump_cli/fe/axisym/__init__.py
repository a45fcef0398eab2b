"""The axisymmetric solve of one scene (docs/physics.md sections 3-5): :mod:`.model` (mesh +
materials -> the problem interface: ``Model``, its linearisation and the bordered solver),
:mod:`.snap` (the continuation's stop criterion: the upper state at ``V*`` and the lower state on
the path), :mod:`.lower_state` (the lower state, on the path or off it at fixed volume) with
:mod:`.descent` (the energy descent at fixed volume, its fallback), :mod:`.metrics` (the snap's
metrics and curve), :mod:`.fluid` and :mod:`.air_snap` (inflating with air).

Imported by module (``from snapjump_cli.fe.axisym.model import Model``)."""
