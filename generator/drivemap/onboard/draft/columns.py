"""Header and column recognition: which column holds the address, the name, the type, the unit ...

A header row is recognised by its words in English and Chinese; without one, the address column
is the one whose cells read as addresses. A header that repeats its columns side by side
(``Register | P_ | Register | P_``) is split into one layout per repetition.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from drivemap.onboard.draft.cells import Address, parse_access, parse_address

_ROLES: tuple[tuple[str, str], ...] = (
    ("hi_byte", r"hi(gh)?\s*byte|高位元組|高字节|高位字节"),
    ("lo_byte", r"lo(w)?\s*byte|低位元組|低字节|低位字节"),
    ("length", r"length|size|words|quantity|no\.?\s*of\s*reg|number\s*of\s*reg|reg(ister)?s?\s*count|"
               r"长度|長度|字数|字數|bytes|l(?:ä|ae)nge|anzahl"),
    ("function_code", r"function\s*code|func\.?\s*code|^fc$|功能码|功能碼"),
    ("table", r"^reg(ister)?\.?\s*type$|^register\s*kind$|^object\s*type$|^寄存器类型$|^寄存器類型$"),
    ("type", r"data\s*type|type|format|datentyp|^typ$|数据类型|資料型態|资料类型|类型|類型|格式"),
    ("scale", r"^scal|scale\s*factor|^factor|multiplier|^gain|multiplikator|^faktor|skalierung|倍率|系数|係數"),
    ("unit", r"unit|resolution|einheit|auflösung|aufloesung|单位|單位|分辨率"),
    ("default", r"default|factory|initial|初始值|出厂|出廠|默认|預設|预设"),
    ("min", r"^min(imum)?\b"),
    ("max", r"^max(imum)?\b"),
    ("range", r"range|limit|bereich|范围|範圍|設定值|设定值"),
    ("access", r"access|^r\s*/\s*w|^w\s*/\s*r$|read\s*/\s*write|^rw$|attribute|zugriff|读写|讀寫|属性|屬性|permission"),
    ("bit", r"^bits?$|^位$|^register[-\s]*bits?$"),
    ("param", r"^id$|^p_?$|^no\.?$|param(eter)?\s*(no|id|number|code|#)|参数号|參數號|参数编号|參數編號"),
    ("address", r"addr|\badr|register|^reg\b|reg\.|寄存器|暂存器|暫存器|位址|地址|modbus|offset|编号|編號|pdu|"
                r"^coils?$|^discrete\s+inputs?$|^线圈$|^線圈$"),
    ("name", r"name|parameter|function|item|measur|signal|variable|quantity|object|名稱|名称|功能|项目|項目|参数|參數"),
    ("description", r"descr|decrip|content|definition|meaning|note|remark|comment|detail|data|beschreibung|"
                    r"erl(?:ä|ae)uterung|bemerkung|hinweis|說明|说明|內容|内容|含义|含義|意义"),
)
_RADIX_HEX = re.compile(r"hex|\(h\)|16\s*进制|16\s*進位|十六", re.I)
#: an address column headed as an offset (``Offset``, ``偏移``, ``Index``) and not as an address: its numbers
#: count from a base the rows do not give (a block's start address), in words or in bytes
_RELATIVE = re.compile(r"offset|偏移|\bindex\b", re.I)
_ABSOLUTE = re.compile(r"addr|\badr\b|地址|位址|register|寄存器|modbus|pdu", re.I)


def relative_header(header: str) -> bool:
    """Whether an address column's header says its numbers are offsets, not addresses."""
    return bool(_RELATIVE.search(header)) and not _ABSOLUTE.search(header)

_RADIX_DEC = re.compile(r"\bdec|十进制|十進位|10\s*进制|10\s*進位", re.I)


_REGISTER_FACTS = {"type", "unit", "scale", "access", "range", "default", "min", "max", "length"}
"""Columns that make a table headed ``NO. | Name | ...`` a register list rather than a numbered list."""


@dataclass
class Layout:
    """Column roles of one table (or one repeated group of a side-by-side table)."""

    roles: dict[str, int] = field(default_factory=dict)
    headers: dict[str, str] = field(default_factory=dict)
    radix: str | None = None
    """``hex`` or ``dec`` when the header says it."""
    header_row: int | None = None
    header_rows: int = 1
    """2 when the header goes on in the next row (``Data`` / ``format``)."""
    other_address: int | None = None
    """A second address column whose header does not say hex (``Register Address | Modbus Address``)."""
    other_header: str = ""


#: "Register name", "Register meaning", "寄存器名", "寄存器含义": the register's name, not its address
_REGISTER_NAMED = re.compile(r"(?:regist|寄存器|暂存器|暫存器).*(?:name|meaning|descr|名|含义|含義|意义|说明|說明)", re.I)
_ADDRESS_SAID = re.compile(r"addr|地址|位址|number|\bno\b|编号|編號|offset|modbus", re.I)


def role_of(text: str) -> str | None:
    """The role a header cell names; a word broken over two lines (``Registe`` / ``rNO.``) is read whole.
    A header naming a register's name or meaning (``Register meaning``, ``寄存器名``) is a name column, though
    it starts with the word that usually heads the address column."""
    low = re.sub(r"\s+", " ", text.strip().lower())
    low = re.sub(r"(?<=[\u4e00-\u9fff]) (?=[\u4e00-\u9fff])", "", low)
    if _REGISTER_NAMED.search(low) and not _ADDRESS_SAID.search(low):
        return "name"
    for candidate in (low, low.replace(" ", "")):
        for role, pattern in _ROLES:
            if candidate and re.search(pattern, candidate, re.I):
                return role
    return None


#: a unit column whose header also names the quantity (``VARIABLE / ENG. UNIT``): its cells print both,
#: ``V L1-N`` (the name column too, when no other column is one)
_NAMES_UNIT = re.compile(r"variable|quantity|measur|\bname", re.I)


def _layout_of(header: list[str], offset: int = 0) -> Layout:
    layout = Layout()
    for i, cell in enumerate(header):
        role = role_of(cell)
        if role == "address" and "address" in layout.roles:
            if _RADIX_HEX.search(cell) and not _RADIX_HEX.search(layout.headers["address"]):
                layout.roles["address_dec"] = layout.roles["address"]
                layout.roles["address"], layout.headers["address"] = i + offset, cell
            elif layout.other_address is None:
                layout.other_address, layout.other_header = i + offset, cell
            continue
        if role == "name" and "name" in layout.roles:
            role = "description"
        if role is None or role in layout.roles:
            continue
        layout.roles[role], layout.headers[role] = i + offset, cell
        if role == "address":
            layout.radix = "hex" if _RADIX_HEX.search(cell) else "dec" if _RADIX_DEC.search(cell) else None
    if "name" not in layout.roles and "unit" in layout.roles and _NAMES_UNIT.search(layout.headers["unit"]):
        layout.roles["name"], layout.headers["name"] = layout.roles["unit"], layout.headers["unit"]
    if "name" not in layout.roles and "description" in layout.roles:
        layout.roles["name"] = layout.roles.pop("description")
        layout.headers["name"] = layout.headers.pop("description")
    if "address" not in layout.roles and re.fullmatch(r"\s*no\.?\s*", layout.headers.get("param", ""), re.I) \
            and "name" in layout.roles and set(layout.roles) & _REGISTER_FACTS:
        layout.roles["address"] = layout.roles.pop("param")  # "NO. | Variable Name | ... | Unit": the register number
        layout.headers["address"] = layout.headers.pop("param")
    return layout


def _groups(header: list[str]) -> list[tuple[int, list[str]]]:
    """A header that repeats the same columns side by side -> (offset, cells) per repetition."""
    cells = [c.strip() for c in header]
    while cells and not cells[-1]:
        cells.pop()
    for width in range(1, len(cells) // 2 + 1):
        if len(cells) % width:
            continue
        first = [role_of(c) for c in cells[:width]]
        if "address" not in first:
            continue
        if all([role_of(c) for c in cells[k:k + width]] == first for k in range(width, len(cells), width)):
            return [(k, cells[k:k + width]) for k in range(0, len(cells), width)]
    return [(0, cells)]


def header_index(rows: list[list[str]]) -> int | None:
    """The header row among the first rows: the one naming an address column and the most roles."""
    best: tuple[int, int] | None = None
    for index, row in enumerate(rows[:4]):
        roles = set(_layout_of(row).roles)
        if ("address" in roles or {"hi_byte", "lo_byte"} <= roles) and len(roles) >= 2:
            if best is None or len(roles) > best[1]:
                best = (index, len(roles))
    return None if best is None else best[0]


def _two_row_header(header: list[str], below: list[str]) -> list[str] | None:
    """The header joined with the row below it when that row goes on with the header's words: every
    cell of it makes a role with the header cell above, and the roles change but are no fewer
    (``Data`` + ``format``: a type column, not a description)."""
    texts = [(i, c.strip()) for i, c in enumerate(below) if c.strip()]
    if not texts or any(parse_address(c) is not None for _, c in texts):
        return None
    joined = [f"{h} {below[i]}".strip() if i < len(below) else h for i, h in enumerate(header)]
    if len(below) > len(header) or any(role_of(joined[i]) is None for i, _ in texts):
        return None
    before, after = set(_layout_of(header).roles), set(_layout_of(joined).roles)
    if after == before or len(after) < len(before) or not after & {"address", "hi_byte"}:
        return None
    return joined


def find_layouts(rows: list[list[str]]) -> list[Layout]:
    """Layouts from the header row among the first rows; [] if none names an address column."""
    index = header_index(rows)
    if index is None:
        return []
    header = rows[index]
    joined = _two_row_header(header, rows[index + 1]) if index + 1 < len(rows) else None
    layouts = []
    for offset, cells in _groups(joined or header):
        layout = _layout_of(cells, offset)
        layout.header_row, layout.header_rows = index, 2 if joined else 1
        _prefer_marked(layout, rows[index + layout.header_rows:])
        _access_by_values(layout, rows[index + layout.header_rows:], offset, cells)
        _prefer_distinct_name(layout, rows[index + layout.header_rows:])
        layouts.append(layout)
    return layouts


def _access_by_values(layout: Layout, rows: list[list[str]], offset: int, header: list[str]) -> None:
    """Without a column headed as access, a column every filled cell of which reads as an access
    (``r``, ``w``, ``r/w``, ``RO``; ``-`` says nothing) is the access column, whatever its header says
    (``EVCC-Home MODBUS RTU``): a second address column never holds such cells."""
    if "access" in layout.roles:
        return
    taken = {i for role, i in layout.roles.items() if role not in ("description",)}
    for col in range(offset, offset + len(header)):
        if col in taken:
            continue
        cells = [r[col].strip() for r in rows if col < len(r) and r[col].strip() not in ("", "-", "–")]
        if len(cells) >= 3 and all(parse_access(c) is not None for c in cells):
            if layout.roles.get("description") == col:
                del layout.roles["description"], layout.headers["description"]
            if layout.other_address == col:
                layout.other_address, layout.other_header = None, ""
            layout.roles["access"], layout.headers["access"] = col, header[col - offset]
            return


def _prefer_distinct_name(layout: Layout, rows: list[list[str]]) -> None:
    """A name column that repeats a few values (``dbus-service-name``: ``com.victronenergy.system`` on
    every row of a section) names groups, not registers: the description column, a different text on
    most rows, names the registers then."""
    name, description = layout.roles.get("name"), layout.roles.get("description")
    if name is None or description is None:
        return

    def texts(col: int) -> list[str]:
        return [r[col].strip() for r in rows if col < len(r) and r[col].strip()]

    names, descriptions = texts(name), texts(description)
    if len(names) < 10 or len(descriptions) < 0.9 * len(names):
        return
    distinct = len(set(descriptions))
    if len(set(names)) <= 0.2 * len(names) and distinct >= 0.5 * len(descriptions) and distinct >= 4 * len(set(names)):
        layout.roles["name"], layout.roles["description"] = description, name
        layout.headers["name"], layout.headers["description"] = layout.headers["description"], layout.headers["name"]


def _prefer_marked(layout: Layout, rows: list[list[str]]) -> None:
    """Of two address columns, the one printed ``0x00`` is the protocol address when the other holds
    plain numbers that are not Modicon 3xxxx/4xxxx numbers (``Register Address 0001 | Modbus Address
    0x00``, ``10001 | 0x00``: coil and discrete-input numbers counted from 1)."""
    first, other = layout.roles.get("address"), layout.other_address
    if first is None or other is None or layout.radix is not None:
        return

    def parsed(col: int) -> list[Address]:
        cells = [r[col] for r in rows if col < len(r) and r[col].strip()]
        found = [parse_address(c) for c in cells]
        return [a for a in found if a is not None] if all(found) else []

    plain, marked = parsed(first), parsed(other)
    if len(plain) < 2 or len(marked) != len(plain) or not all(a.marked for a in marked):
        return
    if any(a.marked for a in plain) or all(30001 <= (a.dec_value or 0) <= 49999 for a in plain):
        return
    layout.roles["address_dec"], layout.headers["address_dec"] = first, layout.headers["address"]
    layout.roles["address"], layout.headers["address"], layout.radix = other, layout.other_header, "hex"


def content_layout(rows: list[list[str]]) -> Layout | None:
    """No header: the column most of whose cells are hex-marked addresses, the next text column the name.
    A table whose first row is a header that names no address column is no register table."""
    first = rows[0] if rows else []
    if first and (parse_address(first[0]) is None or not parse_address(first[0]).marked):  # type: ignore[union-attr]
        return None
    width = max((len(r) for r in rows), default=0)
    for col in range(min(width, 1)):
        cells = [r[col] for r in rows if col < len(r) and r[col].strip()]
        hits = [a for a in (parse_address(c) for c in cells) if a is not None and a.marked]
        distinct = len({a.hex_value for a in hits}) == len(hits)
        if len(cells) >= 3 and len(hits) >= 0.6 * len(cells) and distinct:
            layout = Layout(roles={"address": col}, headers={"address": ""})
            for other in range(col + 1, width):
                texts = [r[other] for r in rows if other < len(r) and re.search(r"[A-Za-z\u4e00-\u9fff]{2}", r[other])]
                if len(texts) >= 0.5 * len(cells):
                    layout.roles["name"] = other
                    break
            return layout
    return None
