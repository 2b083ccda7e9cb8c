"""The topology every layer derives from (fmus/mechanism/topology.py): the 3PRS's, and bad ones refused."""

import pytest

from fmus.mechanism.designs import describe
from fmus.mechanism.topology import Coordinate, Drive, Topology, TopologyError
from mast.core.build import default_parameters


def test_the_3prs_topology_is_three_linear_drives_and_z_psi_theta():
    params = default_parameters("MastMechanism")
    desc = describe(params)
    top = desc.topology
    assert top.n == 3 and top.names == ("z", "psi", "theta") and top.joints == ("rho_1", "rho_2", "rho_3")
    assert [c.unit for c in top.coordinates] == ["m", "rad", "rad"]
    assert [c.name for c in top.parasitic] == ["x", "y", "phi"]
    # home: the level pose with the sliders at mid-stroke, whose inverse kinematics gives them back
    assert top.home[1:] == (0.0, 0.0)
    rho = [float(v) for v in desc.evaluate(list(top.home)).rho]
    assert rho == pytest.approx([0.15] * 3, abs=1e-12)


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda: Coordinate("w"), "coordinate 'w'"),
        (lambda: Drive("rho_1", "hydraulic", (0.0, 1.0)), "kind 'hydraulic'"),
        (lambda: Drive("rho_1", "linear", (0.3, 0.0)), "lower < upper"),
        (lambda: Topology("T", (Coordinate("z"),), (), (0.0,)), "0 drives for 1 coordinates"),
        (
            lambda: Topology("T", (Coordinate("z"), Coordinate("z")), (Drive("a", "linear", (0, 1)),) * 2, (0, 0)),
            "each pose component at most once",
        ),
        (lambda: Topology("T", (Coordinate("z"),), (Drive("a", "linear", (0, 1)),), (0.0, 1.0)), "expected 1 finite"),
    ],
)
def test_a_bad_topology_is_refused_naming_what(make, words):
    with pytest.raises(TopologyError, match=words.replace("(", r"\(").replace(")", r"\)")):
        make()
