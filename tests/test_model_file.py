"""Reading model files: what is accepted, and every kind of bad input refused
with a ModelError (a ValueError) that names the file, the item and the field.

Each bad input is its own test, built by spoiling one line of a small valid
model, so a failure points at one check.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import ModelError

SRC = "bad.toml"

BEAM = """
[[node]]
id = "p"
at = [0.0, 0.0]

[[node]]
id = "q"
at = [1.0, 0.0]

[[beam]]
id = "bar"
nodes = ["p", "q"]
E = 2.1e11
rho = 7850.0
A = 0.01
I = 1.0e-5

[[support]]
node = "p"
"""

SECOND_BODY = '[[body]]\nid = "b2"\nmass = 10.0\ninertia = 1.0\ncentre = [1.0, 0.0]\n'


def refuse(text: str, *fragments: str, variant: str | None = None, stage: str = "load") -> ModelError:
    """Load (and, for ``stage`` "assemble"/"modes", assemble and analyse) a
    model that must be refused; check the error is a ModelError and a
    ValueError whose message holds the file name and every fragment."""
    with pytest.raises(ModelError) as info:
        model = cl.loads_model(text, source=SRC, variant=variant)
        if stage in ("assemble", "modes"):
            system = cl.assemble(model)
            if stage == "modes":
                cl.modes(system)
    err = info.value
    assert isinstance(err, ValueError)
    msg = str(err)
    assert SRC in msg, msg
    for f in fragments:
        assert f in msg, f"{f!r} not in {msg!r}"
    return err


# --------------------------------------------------------------------------- accepted input


def test_minimal_model_reads_back_its_values(block_text):
    m = cl.loads_model(block_text(), source="ok.toml")
    body = m.item("block")
    assert (body.mass, body.inertia, body.centre) == (100.0, 2.0, (0.0, 0.0))
    sp = m.item("mount")
    assert sp.c == (1.0e7, 2.0e7, 3.0e5) and sp.d == (0.0, 0.0, 0.0) and sp.angle == 0.0
    assert m.source == "ok.toml"
    assert m.summary()["bodies"] == 1


def test_beam_shear_modulus_from_poisson_ratio_or_given(beam_model_text):
    m = cl.loads_model(beam_model_text(1.0, 0.1, nu=0.25))
    # G = E / (2 (1 + nu)): one division, exact to round-off
    assert m.item("beam").section.G == pytest.approx(2.1e11 / 2.5, rel=1e-15)
    text = beam_model_text(1.0, 0.1).replace("nu = 0.3\n", "G = 8.0e10\n")
    assert cl.loads_model(text).item("beam").section.G == 8.0e10
    assert cl.loads_model(text).item("beam").section.kappa == pytest.approx(5 / 6, rel=1e-15)


def test_spring_angle_is_read_in_degrees(block_text):
    m = cl.loads_model(block_text().replace("c6 = 3.0e5\n", "c6 = 3.0e5\nangle_deg = 30.0\n"))
    assert m.item("mount").angle == pytest.approx(math.pi / 6, rel=1e-15)


def test_with_parameter_returns_a_changed_copy(block_text):
    m = cl.loads_model(block_text(), source="ok.toml")
    m2 = m.with_parameter("spring.mount.c2", 5.0e7)
    assert m2.item("mount").c == (1.0e7, 5.0e7, 3.0e5)
    assert m.item("mount").c == (1.0e7, 2.0e7, 3.0e5)  # the original is untouched
    assert m2.source == "ok.toml"
    with pytest.raises(ModelError, match="nosuch"):
        m.with_parameter("spring.nosuch.c2", 1.0)
    # a changed copy is validated like a file
    with pytest.raises(ModelError, match="c2"):
        m.with_parameter("spring.mount.c2", -1.0)


# --------------------------------------------------------------------------- refused input


def test_unknown_id_referenced(block_text):
    refuse(block_text().replace('b = "ground"', 'b = "nosuch"'), '[[spring]] "mount"', "b:", "'nosuch'")


def test_unknown_node_of_a_beam():
    refuse(BEAM.replace('nodes = ["p", "q"]', 'nodes = ["p", "r"]'), '[[beam]] "bar"', "nodes", "'r'")


def test_duplicate_ids(block_text):
    refuse(block_text(SECOND_BODY.replace('"b2"', '"block"')), '[[body]] "block"', "duplicate id 'block'")


def test_duplicate_ids_across_kinds(block_text):
    refuse(
        block_text('[[node]]\nid = "block"\nat = [0.0, 0.0]\n'), '[[node]] "block"', "duplicate", "[[body]]"
    )


def test_missing_field(block_text):
    refuse(block_text().replace("mass = 100.0\n", ""), '[[body]] "block"', "mass", "missing")


def test_missing_id(block_text):
    refuse(block_text().replace('id = "mount"\n', ""), "[[spring]] #1", "id")


def test_negative_mass(block_text):
    refuse(block_text(mass=-100.0), '[[body]] "block"', "mass", ">= 0")


def test_zero_mass_with_inertia(block_text):
    refuse(block_text(mass=0.0), '[[body]] "block"', "mass", "both")


def test_zero_length_beam():
    refuse(BEAM.replace("at = [1.0, 0.0]", "at = [0.0, 0.0]"), '[[beam]] "bar"', "nodes", "zero length")


def test_zero_area():
    refuse(BEAM.replace("A = 0.01", "A = 0.0"), '[[beam]] "bar"', "A:", "> 0")


def test_negative_second_moment():
    refuse(BEAM.replace("I = 1.0e-5", "I = -1.0e-5"), '[[beam]] "bar"', "I:", "> 0")


def test_all_zero_spring(block_text):
    text = block_text().replace("c1 = 1.0e7\nc2 = 2.0e7\nc6 = 3.0e5", "c1 = 0.0")
    refuse(text, '[[spring]] "mount"', "c1", "all are zero")


def test_negative_stiffness(block_text):
    refuse(block_text().replace("c1 = 1.0e7", "c1 = -1.0e7"), '[[spring]] "mount"', "c1", ">= 0")


def test_spring_point_outside_its_beam(block_text):
    text = (
        BEAM
        + block_text().replace("centre = [0.0, 0.0]", "centre = [1.5, 0.0]")
        + '[[spring]]\nid = "s2"\na = { beam = "bar", distance = 1.5 }\nb = "block"\nc1 = 1.0e6\n'
    )
    refuse(text, '[[spring]] "s2"', "a.distance", "outside its beam", "[0, 1]")


def test_misspelt_field_suggests_the_right_one(block_text):
    err = refuse(
        block_text().replace("inertia", "inertai"), '[[body]] "block"', "'inertai'", "Did you mean 'inertia'?"
    )
    assert err.field == "inertai"


def test_misspelt_table_suggests_the_right_one(block_text):
    refuse(block_text().replace("[[spring]]", "[[sprung]]"), "'sprung'", "Did you mean 'spring'?")


def test_singular_constraint(block_text):
    """A [[constraint]] whose dependent coordinate b2.y appears in no equation:
    W_d^T W_d of Eq. 2.6 is singular, found at assembly."""
    text = block_text(
        SECOND_BODY
        + '[[constraint]]\nid = "tie"\ndependent = ["b2.x", "b2.y"]\n'
        + 'equations = [{ "b2.x" = 1.0, "block.x" = -1.0 }]\n'
    )
    refuse(text, '[[constraint]] "tie"', "dependent", "b2.y", "singular", stage="assemble")


def test_constraint_naming_an_unknown_coordinate(block_text):
    text = block_text('[[constraint]]\nid = "tie"\ndependent = ["b9.x"]\nequations = [{ "b9.x" = 1.0 }]\n')
    refuse(text, '[[constraint]] "tie"', "dependent", "'b9.x'")


def test_structure_not_held_by_the_foundation(block_text):
    """A second body connected to nothing: modes() names it."""
    err = refuse(block_text(SECOND_BODY), "not held by the foundation", "b2", stage="modes")
    assert "block" not in str(err).split("moves", 1)[1]  # the held body is not blamed


def test_file_that_is_not_toml(tmp_path):
    p = tmp_path / "notes.toml"
    p.write_text("this is = not [toml\n")
    with pytest.raises(ModelError) as info:
        cl.load_model(p)
    assert isinstance(info.value, ValueError)
    assert str(p) in str(info.value) and "not valid TOML" in str(info.value)


def test_binary_file(tmp_path):
    p = tmp_path / "model.toml"
    p.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(ModelError, match="UTF-8"):
        cl.load_model(p)


def test_missing_file(tmp_path):
    with pytest.raises(ModelError, match="not found"):
        cl.load_model(tmp_path / "nosuch.toml")


def test_massless_body_with_independent_coordinates(block_text):
    refuse(block_text(mass=0.0, inertia=0.0), '[[body]] "block"', "mass", "block.x", "massless")


def test_spring_ends_do_not_coincide(block_text):
    text = block_text(SECOND_BODY + '[[spring]]\nid = "link"\na = "block"\nb = "b2"\nc1 = 1.0e6\n')
    err = refuse(text, '[[spring]] "link"', "1 m apart", "coincide")
    assert err.field == "b"


def test_beam_point_and_body_point_that_do_not_coincide(block_text):
    text = BEAM + block_text(
        '[[spring]]\nid = "s2"\na = { beam = "bar", distance = 0.5, offset = 0.1 }\nb = "block"\nc1 = 1.0e6\n'
    )
    refuse(text, '[[spring]] "s2"', "apart")


def test_contact_leaving_its_track():
    text = (
        BEAM
        + '[movable]\nbodies = ["cart"]\nposition = 0.5\nrange = [0.0, 1.5]\n'
        + '[[body]]\nid = "cart"\nmass = 5.0\ninertia = 0.1\ncentre = [0.5, 0.2]\n'
        + '[[spring]]\nid = "cart-ground"\na = "cart"\nb = "ground"\nc1 = 1e6\nc2 = 1e6\nc6 = 1e4\n'
        + '[[contact]]\nid = "touch"\nbeams = ["bar"]\nfollows = "cart"\n'
    )
    refuse(text, '[[contact]] "touch"', "beams", "s = 1.5 m", "leaves the beams bar")


def test_unknown_variant(block_text):
    refuse(block_text(), "variant 'nosuch' is not defined", variant="nosuch")


def test_unknown_variant_lists_the_known_ones(shaper_path):
    with pytest.raises(ModelError) as info:
        cl.load_model(shaper_path, variant="printd")
    assert str(shaper_path) in str(info.value) and "printed" in str(info.value)


def test_number_given_as_string(block_text):
    refuse(block_text().replace("mass = 100.0", 'mass = "100"'), '[[body]] "block"', "mass", "number")


def test_movable_body_that_does_not_exist(block_text):
    refuse(block_text('[movable]\nbodies = ["ghost"]\nposition = 0.0\n'), "[movable]", "bodies", "'ghost'")


# --------------------------------------------------------------------------- matrix-level input


def _matrix_text(M, K, coords=("q1", "q2", "q3")) -> str:
    def rows(X):
        return "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in r) + "]" for r in np.asarray(X)) + "]"

    names = ", ".join(f'"{c}"' for c in coords)
    return f"[matrices]\ncoordinates = [{names}]\nM = {rows(M)}\nK = {rows(K)}\n"


M3 = np.diag([2.0, 1.0, 3.0])
K3 = np.array([[3.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.5]]) * 1e6


def test_matrix_model_reads_inline_matrices():
    m = cl.loads_model(_matrix_text(M3, K3))
    assert m.is_matrix_model
    np.testing.assert_array_equal(m.matrices.M, M3)
    np.testing.assert_array_equal(m.matrices.K, K3)
    np.testing.assert_array_equal(m.matrices.L, np.zeros((3, 3)))
    assert not m.matrices.K.flags.writeable  # models are immutable


def test_matrix_model_refuses_a_non_symmetric_matrix():
    K = K3.copy()
    K[0, 1] += 1.0e3
    refuse(_matrix_text(M3, K), "[matrices]", "K:", "symmetric")


def test_matrix_model_refuses_a_wrong_shape():
    refuse(_matrix_text(M3[:2], K3), "[matrices]", "M:", "must be 3x3", "(2, 3)")


def test_matrix_model_refuses_a_matrix_of_another_size_than_the_coordinates():
    refuse(_matrix_text(M3, K3, coords=("q1", "q2")), "[matrices]", "must be 2x2")


def test_matrix_model_refuses_a_singular_mass():
    refuse(_matrix_text(np.diag([1.0, 0.0, 1.0]), K3), "[matrices]", "M:", "positive definite")


def test_matrix_model_refuses_a_ragged_matrix():
    text = _matrix_text(M3, K3).replace("K = [[", "K = [[1.0], [")
    refuse(text, "[matrices]", "K")


def test_matrix_model_refuses_a_missing_matrix_file(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text('[matrices]\ncoordinates = ["a"]\nM = "nosuch.mtx"\nK = [[1.0]]\n')
    with pytest.raises(ModelError, match="nosuch.mtx.*not found"):
        cl.load_model(p)


def test_matrix_model_refuses_structural_items_too(block_text):
    refuse(block_text(_matrix_text(M3, K3)), "[matrices]", "either structural")


def test_inconsistent_constraints(block_text):
    """Four equations for three dependent coordinates that cannot all hold
    (ghost.y = block.y and ghost.y = block.x would tie block.x to block.y):
    Eq. 2.6 would return a silent least-squares compromise."""
    text = block_text(
        '[[body]]\nid = "ghost"\nmass = 0.0\ninertia = 0.0\ncentre = [0.0, -0.5]\n'
        '[[constraint]]\nid = "arm"\ndependent = ["ghost.x", "ghost.y", "ghost.rz"]\n'
        'equations = [{ "ghost.x" = 1.0, "block.x" = -1.0, "block.rz" = -0.5 },'
        ' { "ghost.y" = 1.0, "block.y" = -1.0 }, { "ghost.rz" = 1.0, "block.rz" = -1.0 },'
        ' { "ghost.y" = 1.0, "block.x" = -1.0 }]\n'
    )
    refuse(text, '[[constraint]] "arm"', "equations", "cannot all hold", stage="assemble")


def test_with_parameter_accepts_numpy_scalars(beam_model_text):
    """Sweep grids hold numpy scalars (np.int64 from arange, np.float32...):
    they are the same numbers as in a file."""
    m = cl.loads_model(beam_model_text(1.0, 0.1))
    m2 = m.with_parameters({"beam.beam.elements": np.arange(1, 5)[2], "beam.beam.A": np.float32(0.25)})
    assert m2.item("beam").elements == 3 and isinstance(m2.item("beam").elements, int)
    assert m2.item("beam").section.A == float(np.float32(0.25))
    with pytest.raises(ModelError, match="elements"):
        m.with_parameter("beam.beam.elements", np.float64(2.5))
    with pytest.raises(ModelError, match="A"):
        m.with_parameter("beam.beam.A", np.bool_(True))
