"""Session 25 (helper fixal): simulate_plant's words for a physics run that never moved are simulate's.
A static friction of 630 N (just below the 633.3 N the supply gives retracting) holds the piston
against 40-count commands, beyond the valves' deadzone of 255 * 0.4 / 10 = 10.2 counts: the warning
names the friction, not the command scale; 8 counts (inside the deadzone) keep the scale words."""

import warnings

import ipa_sysid


def _said(**kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ipa_sysid.simulate_plant("ipa", samples=300, **kw)
    return [str(w.message) for w in caught if issubclass(w.category, ipa_sysid.IpaSysidWarning)]


def test_friction_is_named_beyond_the_deadzone(tmp_path):
    cfg = tmp_path / "sticky.toml"
    cfg.write_text("[friction]\nstatic_n = 630.0\ncoulomb_n = 100.0\n")
    said = _said(input="step:40@0", plant_config=str(cfg))
    flat = [w for w in said if "never moved" in w]
    assert len(flat) == 1, said
    assert "static friction holds the piston" in flat[0], flat
    assert "friction.static_n = 630.0 N" in flat[0], flat
    assert "beyond the valves' deadzone (±10.2000 counts)" in flat[0], flat


def test_commands_inside_the_deadzone_keep_the_scale_words():
    said = _said(input="step:8@0")
    assert any("the commands stay within ±8.0000 counts, inside the valves' deadzone" in w
               for w in said), said
    assert not any("friction" in w for w in said), said
