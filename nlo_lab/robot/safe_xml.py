"""XML from files we did not write (URDFs, COLLADA meshes), parsed without entities or external references.

lxml is asked not to resolve entities, not to load a DTD and not to touch the network, and
a document that declares a DTD at all (``<!DOCTYPE``, which is where entities are declared)
is refused: a URDF or a COLLADA file never needs one. So a "billion laughs" file, an
external entity (``SYSTEM "file:///etc/passwd"``) or a DTD fetched from the network is one
:class:`~nlo_lab.errors.RobotDescriptionError`, never expanded, read or fetched.
"""

from __future__ import annotations

from pathlib import Path

from nlo_lab.errors import RobotDescriptionError, escape

__all__ = ["parse_xml"]


def _parser(huge: bool):
    # lazy: the XML parser: only when a URDF is read
    from lxml import etree

    return etree.XMLParser(
        resolve_entities=False, load_dtd=False, dtd_validation=False, no_network=True, huge_tree=huge, remove_blank_text=True
    )


def parse_xml(data: bytes, where: str | Path, huge: bool = False):
    """Parse ``data`` (the bytes of a file) into an lxml element tree, or one clear error.

    Args:
        data: the whole document.
        where: the file, for the message.
        huge: lift libxml2's limits on text size and depth (COLLADA meshes keep megabytes of
            numbers in one text node); entities and DTDs stay refused, and the caller bounds the size.

    Returns:
        The root element.

    Raises:
        RobotDescriptionError: malformed XML, or a document that declares a DTD or entities.
    """
    # lazy: the XML parser: only when a URDF is read
    from lxml import etree

    try:
        tree = etree.ElementTree(etree.fromstring(data, parser=_parser(huge)))
    except etree.XMLSyntaxError as exc:
        raise RobotDescriptionError(f"{where}: malformed XML ({escape(exc)})") from None
    except ValueError as exc:  # e.g. an encoding declaration lxml refuses
        raise RobotDescriptionError(f"{where}: malformed XML ({escape(exc)})") from None
    info = tree.docinfo
    if info.doctype or info.internalDTD is not None or info.externalDTD is not None:
        raise RobotDescriptionError(f"{where}: the XML declares a DTD (<!DOCTYPE ...>); entities and external references are refused")
    root = tree.getroot()
    for node in root.iter():
        if node.tag is etree.Entity:  # an entity reference kept unresolved
            raise RobotDescriptionError(f"{where}: the XML uses an entity (&{escape(node.name)};); entities are refused")
    return root
