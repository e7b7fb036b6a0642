"""YAML read with bounds: a hostile or mistyped file gives one InputError line, never a blow-up.

PyYAML's safe loader builds no objects from tags, but it still follows aliases (shared, so a
billion-laughs document of a few hundred bytes loads as a tiny graph that every later walk, such
as a JSON-schema check, expands to 10⁹ nodes), composes nesting by recursion (10,000 brackets
raise RecursionError) and lets the last of two equal keys win. :func:`load_yaml` refuses all
three while the document is composed, before anything big is built, and also refuses files
that are not UTF-8 text or are larger than any configuration file.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml
from yaml.events import AliasEvent, MappingStartEvent, SequenceStartEvent
from yaml.nodes import MappingNode, SequenceNode

from .errors import InputError

__all__ = ["load_yaml", "parse_yaml", "MAX_DEPTH", "MAX_NODES", "MAX_BYTES"]

MAX_DEPTH = 32  # nested lists/mappings; a scene or workflow config uses 3 or 4
MAX_NODES = 100_000  # nodes after expanding every alias; a scene has a few dozen
MAX_BYTES = 16 * 2**20  # a scene or workflow config is a few kB of text

_MERGE_TAG = "tag:yaml.org,2002:merge"


class _Refused(yaml.YAMLError):
    """A document that is valid YAML but exceeds a bound (message already one line)."""

    def __init__(self, problem, mark=None):
        super().__init__(problem)
        self.problem = problem
        self.problem_mark = mark


class _BoundedLoader(yaml.SafeLoader):
    """Safe loader that bounds nesting depth and alias expansion and refuses duplicate keys.

    Also reads exponent floats without a dot (``5e4``, ``1e-3``) as numbers: YAML 1.1, which
    PyYAML implements, reads them as strings; YAML 1.2 and every scientist read them as numbers.
    """

    max_depth = MAX_DEPTH
    max_nodes = MAX_NODES

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0
        # Node id -> number of nodes it stands for once every alias below it is expanded.
        # Aliases share node objects, so each node is sized once from its children's sizes.
        self._expanded = {}

    def compose_node(self, parent, index):
        is_alias = self.check_event(AliasEvent)
        nests = self.check_event(SequenceStartEvent, MappingStartEvent)
        if nests:
            self._depth += 1
            if self._depth > self.max_depth:
                raise _Refused(f"nested deeper than {self.max_depth} levels",
                               self.peek_event().start_mark)
        try:
            mark = self.peek_event().start_mark
            node = super().compose_node(parent, index)
        finally:
            if nests:
                self._depth -= 1
        if is_alias:
            if id(node) not in self._expanded:
                raise _Refused("an alias refers to the node that contains it", mark)
            return node
        if isinstance(node, SequenceNode):
            children = node.value
        elif isinstance(node, MappingNode):
            children = [item for pair in node.value for item in pair]
        else:
            children = ()
        size = 1 + sum(self._expanded[id(child)] for child in children)
        if size > self.max_nodes:
            raise _Refused(f"aliases expand to more than {self.max_nodes} nodes", mark)
        self._expanded[id(node)] = size
        return node

    def construct_mapping(self, node, deep=False):
        if isinstance(node, MappingNode):
            first_line = {}
            for key_node, _ in node.value:
                if key_node.tag == _MERGE_TAG:
                    continue  # '<<' merges are overridden by explicit keys by design
                key = self.construct_object(key_node, deep=True)
                try:
                    hash(key)
                except TypeError:
                    continue  # the base constructor names an unhashable key itself
                line = key_node.start_mark.line + 1
                if key in first_line:
                    raise _Refused(f"duplicate key {key!r} (also on line {first_line[key]})",
                                   key_node.start_mark)
                first_line[key] = line
        return super().construct_mapping(node, deep=deep)


_BoundedLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def _one_line(error):
    """The problem of a YAML error, with its line and column, in one line."""
    mark = getattr(error, "problem_mark", None)
    problem = getattr(error, "problem", None) or (str(error).splitlines() or ["unknown"])[0]
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    return f"{where}{problem}"


def parse_yaml(text, source="<yaml>"):
    """Parse YAML text with the bounds of :func:`load_yaml`.

    Parameters
    ----------
    text : str
        The document.
    source : str or os.PathLike
        Where the text came from, for error messages.

    Returns
    -------
    object
        The parsed document (None for an empty one).

    Raises
    ------
    InputError
        Syntax error, duplicate key, nesting deeper than :data:`MAX_DEPTH`, aliases expanding
        past :data:`MAX_NODES` nodes, or a number Python cannot hold.
    """
    try:
        return yaml.load(text, Loader=_BoundedLoader)
    except _Refused as error:
        raise InputError(source, f"refused YAML ({_one_line(error)})") from None
    except yaml.YAMLError as error:
        raise InputError(source, f"not valid YAML ({_one_line(error)})") from None
    except RecursionError:
        # Last resort: the depth bound should stop nesting long before the stack runs out.
        raise InputError(source, "refused YAML (nested too deeply)") from None
    except ValueError as error:
        # e.g. an integer of more than 4300 digits.
        raise InputError(source, f"not valid YAML ({error})") from None


def load_yaml(path, *, what="file"):
    """Read a YAML file (UTF-8), refusing bombs, deep nesting and duplicate keys.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What the file is, for the message when it cannot be read ("scene file").

    Returns
    -------
    object
        The parsed document (None for an empty file).

    Raises
    ------
    InputError
        One line naming the file: unreadable, larger than :data:`MAX_BYTES`, not UTF-8, not
        valid YAML, a duplicate key (with its line), nesting deeper than :data:`MAX_DEPTH`
        levels, or aliases expanding to more than :data:`MAX_NODES` nodes.
    """
    path = Path(path)
    try:
        with path.open("rb") as stream:
            # In pieces: read(MAX_BYTES + 1) would allocate all of it for a file of a few kB,
            # and a size from stat says nothing for a pipe or a device.
            chunks, size = [], 0
            while size <= MAX_BYTES and (chunk := stream.read(1 << 16)):
                chunks.append(chunk)
                size += len(chunk)
            data = b"".join(chunks)
    except OSError as error:
        raise InputError(path, f"cannot read the {what} ({error.strerror or error})") from None
    if len(data) > MAX_BYTES:
        raise InputError(path, f"refused YAML (larger than {MAX_BYTES // 2**20} MiB)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise InputError(path, f"not a text file in UTF-8 (byte {error.start + 1})") from None
    return parse_yaml(text, path)
