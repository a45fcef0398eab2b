"""snapjump_cli/geometry/designs.yaml: every value is a number (YAML 1.1 reads e.g. ``275e-3`` as a string)."""
from snapjump_cli.geometry.designs import named_designs, paper_values


def test_every_named_design_value_is_numeric():
    for name, entry in named_designs().items():
        for key, value in entry.items():
            assert isinstance(value, (int, float)) and not isinstance(value, bool), (name, key, value)
    assert paper_values("D")["paper_jump_model_m"] == 0.275
