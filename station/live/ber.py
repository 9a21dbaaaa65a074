"""The ASN.1 Basic Encoding Rules the SLE PDUs travel in (ITU-T X.690), as far as the Return
All Frames service needs them: definite lengths only, minimal encodings (so that a DER
decoder reads what is written), tags of the universal and context classes.

A decoded element is a :class:`Tlv`: its class, whether constructed, its tag number and
its content (raw bytes; :meth:`Tlv.children` splits a constructed one).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["BerError", "Tlv", "decode_one", "integer", "null", "octets", "oid", "tlv", "visible"]

UNIVERSAL, CONTEXT = 0x00, 0x80
INTEGER, OCTET_STRING, NULL, OID, SEQUENCE, SET, VISIBLE_STRING = 2, 4, 5, 6, 16, 17, 26


class BerError(ValueError):
    """Bytes that are not a BER element as expected."""


def _length(n: int) -> bytes:
    if n < 0x80:
        return bytes([n])
    raw = n.to_bytes((n.bit_length() + 7) // 8, "big")
    return bytes([0x80 | len(raw)]) + raw


def tlv(cls: int, constructed: bool, number: int, content: bytes) -> bytes:
    """An element: identifier octets (high tag numbers in base 128), length, content."""
    first = cls | (0x20 if constructed else 0)
    if number < 31:
        ident = bytes([first | number])
    else:
        digits = []
        while True:
            digits.append(number & 0x7F)
            number >>= 7
            if not number:
                break
        ident = bytes([first | 31]) + bytes(
            d | (0x80 if k else 0) for k, d in reversed(list(enumerate(digits)))
        )
    return ident + _length(len(content)) + content


def integer(value: int, cls: int = UNIVERSAL, number: int = INTEGER) -> bytes:
    """An INTEGER (two's complement, minimal), universal or implicitly tagged."""
    n = max(1, (value.bit_length() + 8) // 8)
    return tlv(cls, False, number, value.to_bytes(n, "big", signed=True))


def null(cls: int = UNIVERSAL, number: int = NULL) -> bytes:
    return tlv(cls, False, number, b"")


def octets(data: bytes, cls: int = UNIVERSAL, number: int = OCTET_STRING) -> bytes:
    return tlv(cls, False, number, data)


def visible(text: str) -> bytes:
    return tlv(UNIVERSAL, False, VISIBLE_STRING, text.encode("ascii"))


def oid(components: tuple[int, ...]) -> bytes:
    first, second, *rest = components
    body = bytearray([40 * first + second])
    for c in rest:
        chunk = [c & 0x7F]
        c >>= 7
        while c:
            chunk.append(0x80 | (c & 0x7F))
            c >>= 7
        body += bytes(reversed(chunk))
    return tlv(UNIVERSAL, False, OID, bytes(body))


def sequence(*parts: bytes, cls: int = UNIVERSAL, number: int = SEQUENCE) -> bytes:
    """A SEQUENCE (or SEQUENCE OF) of encoded parts, universal or implicitly tagged."""
    return tlv(cls, True, number, b"".join(parts))


@dataclass(frozen=True)
class Tlv:
    """A decoded element."""

    cls: int
    constructed: bool
    number: int
    content: bytes

    def children(self) -> list[Tlv]:
        if not self.constructed:
            raise BerError(f"[{self.number}] is not constructed")
        out, pos = [], 0
        while pos < len(self.content):
            child, pos = decode_one(self.content, pos)
            out.append(child)
        return out

    def integer(self) -> int:
        if self.constructed or not self.content:
            raise BerError(f"[{self.number}] is not an integer")
        return int.from_bytes(self.content, "big", signed=True)

    def text(self) -> str:
        try:
            return self.content.decode("ascii")
        except UnicodeDecodeError:
            raise BerError(f"[{self.number}] is not a visible string") from None

    def oid(self) -> tuple[int, ...]:
        data = self.content
        if not data:
            raise BerError("an empty object identifier")
        out = [min(data[0] // 40, 2), data[0] - 40 * min(data[0] // 40, 2)]
        value = 0
        for b in data[1:]:
            value = (value << 7) | (b & 0x7F)
            if not b & 0x80:
                out.append(value)
                value = 0
        return tuple(out)


def decode_one(data: bytes, pos: int = 0) -> tuple[Tlv, int]:
    """The element at ``pos`` of ``data``, and where the next begins."""
    try:
        first = data[pos]
        pos += 1
        number = first & 0x1F
        if number == 31:
            number = 0
            while True:
                b = data[pos]
                pos += 1
                number = (number << 7) | (b & 0x7F)
                if not b & 0x80:
                    break
        n = data[pos]
        pos += 1
        if n & 0x80:
            k = n & 0x7F
            if k == 0 or k > 4:
                raise BerError("an indefinite or absurd length")
            n = int.from_bytes(data[pos : pos + k], "big")
            pos += k
    except IndexError:
        raise BerError("an element cut short") from None
    if pos + n > len(data):
        raise BerError("an element longer than its container")
    return Tlv(first & 0xC0, bool(first & 0x20), number, data[pos : pos + n]), pos + n
