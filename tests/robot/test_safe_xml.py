"""XML from files we did not write: no entities, no DTD, no external references (nlo_lab.robot.safe_xml)."""

from __future__ import annotations

import pytest

from nlo_lab.errors import RobotDescriptionError
from nlo_lab.robot.safe_xml import parse_xml

ATTACKS = {
    "billion laughs": b'<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">'
                      b'<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">]><robot name="&c;"><link name="x"/></robot>',
    "external entity": b'<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]><robot name="r"><link name="&x;"/></robot>',
    "external DTD": b'<?xml version="1.0"?><!DOCTYPE robot SYSTEM "http://127.0.0.1:9/robot.dtd"><robot name="r"/>',
    "parameter entity": b'<?xml version="1.0"?><!DOCTYPE r [<!ENTITY % p SYSTEM "http://127.0.0.1:9/x">%p;]><robot name="r"/>',
    "undeclared entity": b'<robot name="r"><link name="a">&foo;</link></robot>',
    "UTF-16 DTD": '<?xml version="1.0" encoding="UTF-16"?><!DOCTYPE r [<!ENTITY x "y">]><robot name="r"/>'.encode("utf-16"),
}


@pytest.mark.parametrize("name", sorted(ATTACKS))
def test_entities_and_dtds_are_refused_in_one_line(name):
    with pytest.raises(RobotDescriptionError) as info:
        parse_xml(ATTACKS[name], "robot.urdf")
    text = str(info.value)
    assert text.startswith("robot.urdf: ") and "\n" not in text
    assert "root:" not in text  # nothing of /etc/passwd was read into the message


def test_plain_xml_parses():
    root = parse_xml(b'<?xml version="1.0"?><!-- a comment --><robot name="r"><link name="a"/></robot>', "r.urdf")
    assert root.tag == "robot" and root.find("link").get("name") == "a"
