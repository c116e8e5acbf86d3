"""A dataset request said in the flags of ``cerberus data generate``: the flags that stand for config keys and body
source options, and the command line that resumes a dataset (:func:`generate_command`), which ``cerberus data check``
and the error boundary of every command (an incomplete dataset) name."""
from __future__ import annotations

import json
import shlex
from dataclasses import replace
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cerberus_core.bodies.body import OptionFlag

#: Config keys that ``generate`` also takes as a flag of their own (same as ``--set KEY=...``).
CONFIG_FLAGS = {"seed": "--seed", "image_size": "--image-size", "renderer": "--renderer", "shard_images": "--shard-images"}



def source_flags(dataset: str | None = None) -> dict[str, OptionFlag]:
    """``{option: its flag}`` of the body sources' options that have a flag of their own (each source declares
    them in its ``Options``: :func:`~cerberus_core.bodies.body.flagged`; the folder source's ``--source``,
    ``--test-subjects``...), with the flag written as one (``test_fraction`` → ``--test-fraction``): of the source
    ``dataset``, or of every installed one that loads (the first to take a flag keeps it). Any option is also
    ``--option KEY=VALUE``."""
    from cerberus_core.bodies.body import source_class
    from cerberus_core.errors import CerberusError
    from cerberus_core.plugins import BODY_GROUP, plugin_names

    flags: dict[str, OptionFlag] = {}
    for name in [dataset] if dataset is not None else plugin_names(BODY_GROUP):
        try:
            options = source_class(name).option_flags()
        except CerberusError:  # not installed, or it does not load: its options are --option KEY=VALUE
            continue
        taken = {f.flag for f in flags.values()}
        flags.update({key: replace(flag, flag="--" + flag.flag.replace("_", "-")) for key, flag in options.items()
                      if key not in flags and "--" + flag.flag.replace("_", "-") not in taken})
    return flags


# ------------------------------------------------------------------------------------ what is left to generate
def generate_command(dataset) -> str:  # noqa: ANN001 - a Dataset (imported lazily)
    """The ``cerberus data generate`` command that resumes ``dataset`` (a
    :class:`~cerberus_core.datasets.dataset.Dataset`): its :meth:`~Dataset.request` said in flags. It rebuilds
    exactly the stored config, so ``generate`` resumes instead of refusing a different dataset."""
    import yaml

    request = dataset.request()
    words = ["cerberus", "data", "generate", "--dataset", request.dataset, "--size", request.size,
             "--out", str(dataset.root)]
    flags = source_flags(request.dataset)
    for key, value in request.source_options.items():
        if key in flags:
            words += [flags[key].flag, ",".join(value) if isinstance(value, list) else str(value)]
        else:
            words += ["--option", f"{key}={json.dumps(value)}"]
    for key, value in request.overrides.items():
        text = value if isinstance(value, str) and yaml.safe_load(value) == value else json.dumps(value)
        words += [CONFIG_FLAGS[key], text] if key in CONFIG_FLAGS else ["--set", f"{key}={text}"]
    return shlex.join(words)


def finish(dataset) -> str:  # noqa: ANN001 - a Dataset
    """``finish generating it (it resumes) with `COMMAND```: the fix of an incomplete dataset, in flags."""
    return f"finish generating it (it resumes) with `{generate_command(dataset)}`"


def incomplete_message(exc) -> str:  # noqa: ANN001 - an IncompleteDatasetError
    """An incomplete dataset's error said with the command that finishes it (the CLI's error boundary)."""
    from cerberus_core.datasets.dataset import Dataset
    from cerberus_core.errors import CerberusError

    try:
        return f"{exc.problem}; {finish(Dataset.open(exc.root))}"
    except CerberusError:  # the library's own message, when the command cannot be built
        return str(exc)
