"""Why fmpy could not read a ``modelDescription.xml``, in the terms of the file.

fmpy reads a model description it has not validated (the master does not need the FMI schema's
every rule) and fails, on a faulty one, with Python's words: ``KeyError: 6`` for a
``<ModelStructure>`` entry naming a value reference no variable has, ``int() argument must be
... not 'NoneType'`` for a variable without ``valueReference``, ``invalid literal for int()``,
``'NoneType' object is not iterable`` (no ``<ModelVariables>``), ``KeyError: 'ScalarVariable'``
(FMI 2.0 variables under ``fmiVersion="3.0"``), a multi-line ``ValidationError``.
:func:`explain` finds the cause in the file instead: first the references fmpy follows
(value references of ``<ModelStructure>``, ``dependencies``, ``derivative``, ``<Dimension>``;
FMI 2.0: 1-based indices), then the FMI schema's first complaint (fmpy's own schemas, with the
line), and only then fmpy's message (its first line, without the exception's type).
"""

from __future__ import annotations

from pathlib import Path

#: the variable elements of FMI 3.0 (FMI 2.0: ``ScalarVariable``)
_FMI3_TYPES = ("Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
               "Int64", "UInt64", "Boolean", "String", "Binary", "Enumeration", "Clock")
#: exceptions whose text is Python's, not fmpy's
_PYTHON_WORDS = (KeyError, TypeError, ValueError, AttributeError, IndexError)


def explain(data: bytes, exc: Exception) -> str:
    """One line: why fmpy failed to read the model description ``data`` with ``exc``."""
    try:
        from lxml import etree  # lazy: fmpy's dependency, only for a faulty description

        root = etree.fromstring(data)
    except Exception:  # noqa: BLE001 - not parseable by lxml either: fmpy's words
        return _fmpy_words(exc)
    why = _reference_problem(root) or _schema_problem(root)
    return why or _fmpy_words(exc)


def _fmpy_words(exc: Exception) -> str:
    text = (str(exc).strip().splitlines() or [""])[0].rstrip(":")
    if isinstance(exc, _PYTHON_WORDS) or not text:
        return f"fmpy cannot read it ({type(exc).__name__}: {text})"
    return text


def _where(el) -> str:
    return f"line {el.sourceline}: <{el.tag} ...>"


def _int(text: str | None) -> int | None:
    try:
        return int(text)
    except (TypeError, ValueError):
        return None


def _reference_problem(root) -> str | None:
    """A variable without a usable ``name``/``valueReference``, or a reference to a value
    reference (FMI 3.0) or index (FMI 2.0) no variable has."""
    version = root.get("fmiVersion") or ""
    if version != "2.0" and not version.startswith("3."):
        return f"fmiVersion {version!r}: expected \"2.0\" or \"3.0\""
    mv = root.find("ModelVariables")
    if mv is None:
        return "no <ModelVariables> element (every FMU declares its variables there)"
    fmi2 = version.startswith("2.")
    tags = ("ScalarVariable",) if fmi2 else _FMI3_TYPES
    variables = [el for el in mv if isinstance(el.tag, str)]
    wrong = [el for el in variables if el.tag not in tags]
    if wrong:
        other = "FMI 2.0 <ScalarVariable>" if wrong[0].tag == "ScalarVariable" \
            else f"<{wrong[0].tag}>"
        return (f"{_where(wrong[0])}: a {other} element in <ModelVariables> of an FMU with "
                f"fmiVersion={version!r}")
    known: set[int] = set()
    for el in variables:
        if not el.get("name"):
            return f"{_where(el)}: a variable without a name"
        vr = _int(el.get("valueReference"))
        if vr is None or vr < 0 or vr >= 2**32:
            return (f"{_where(el)}: variable {el.get('name')!r} has valueReference="
                    f"{el.get('valueReference')!r}, expected an unsigned 32-bit integer")
        known.add(vr)
    if fmi2:
        known = set(range(1, len(variables) + 1))  # references are 1-based indices
        what = "index"
    else:
        what = "value reference"
    refs = []
    for el in variables:
        if el.get("derivative") is not None:
            refs.append((el, "derivative", el.get("derivative")))
        for sub in el.iter():
            if isinstance(sub.tag, str) and sub.tag == "Dimension":
                for attr in ("valueReference", "start"):
                    if sub.get(attr) is not None:
                        refs.append((sub, attr, sub.get(attr)))
        if fmi2:
            real = el.find("Real")
            if real is not None and real.get("derivative") is not None:
                refs.append((real, "derivative", real.get("derivative")))
    structure = root.find("ModelStructure")
    for el in (structure.iter() if structure is not None else ()):
        if not isinstance(el.tag, str) or el is structure:
            continue
        for attr in ("index", "valueReference"):
            if el.get(attr) is not None:
                refs.append((el, attr, el.get(attr)))
        for token in (el.get("dependencies") or "").split():
            refs.append((el, "dependencies", token))
    for el, attr, text in refs:
        n = _int(text)
        if n is None:
            return f"{_where(el)}: {attr}={text!r} is not an integer"
        if attr == "start":  # a Dimension's fixed size
            continue
        if n not in known:
            return f"{_where(el)}: {attr} {n} names no variable (no variable has {what} {n})"
    return None


def _schema_problem(root) -> str | None:
    """The FMI schema's first complaint about the model description (fmpy's schemas)."""
    import fmpy  # lazy: as in explain
    from lxml import etree  # lazy: as in explain

    version = root.get("fmiVersion") or ""
    major = "fmi2" if version.startswith("2.") else "fmi3" if version.startswith("3.") else None
    if major is None:
        return None
    name = "fmi2ModelDescription.xsd" if major == "fmi2" else "fmi3ModelDescription.xsd"
    xsd = Path(fmpy.__file__).parent / "schema" / major / name
    try:
        schema = etree.XMLSchema(file=str(xsd))
    except (OSError, etree.XMLSchemaParseError):
        return None
    if schema.validate(root):
        return None
    errors = list(schema.error_log)
    first = errors[0]
    more = f" ({len(errors) - 1} more: uwcosim fmu validate lists them)" if len(errors) > 1 \
        else ""
    return f"line {first.line}: {first.message} (FMI {version} schema){more}"
