"""A sense of rotation is +1 or -1, written as such: a bool is an int to Python (True == 1),
so True would pass as the sense +1 that nobody wrote. Every check that takes a sign (the
ROM's, the nonlinear stages', the scene's) refuses it by name; the signs and the scene's
words still map as documented (rotor 67's table: theta_TE - theta_LE = +0.33 rad, so
'le-leads' is -1)."""
import dataclasses

import numpy as np
import pytest

from hbm.contact.friction import rotation_sense
from rom.rotation import check_sign, rotation_sign
from support import coarse_rom

THETA = np.array([0.0, 0.1, 0.33])  # LE to TE, rad


@pytest.mark.parametrize("check", [check_sign, rotation_sense])
@pytest.mark.parametrize("value", [True, False, np.bool_(True)])
def test_a_bool_is_no_sense(check, value):
    with pytest.raises(ValueError, match="rotation must be"):
        check(value)


@pytest.mark.parametrize("value", [True, np.bool_(True), False])
def test_scene_sign_refuses_a_bool(value):
    with pytest.raises(ValueError, match="bool"):
        rotation_sign(value, THETA)


@pytest.mark.parametrize("value, sign", [(1, 1), (-1, -1), (np.int64(-1), -1), ("+", 1), ("-", -1),
                                         ("le-leads", -1)])
def test_signs_and_words(value, sign):
    assert rotation_sign(value, THETA) == sign


@pytest.mark.parametrize("check", [check_sign, rotation_sense])
def test_signs_pass(check):
    assert check(1) == 1 and check(-1) == -1 and check(np.int32(-1)) == -1


def test_rom_refuses_a_bool_rotation():
    with pytest.raises(ValueError, match="rotation must be"):
        dataclasses.replace(coarse_rom(), rotation=True)
