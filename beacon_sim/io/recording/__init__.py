"""Recordings: every run written as it goes, in JSON Lines, so it can be replayed bit for bit.

The format is described in :mod:`beacon_sim.io.recording.format` and docs/replay.md. The
modules, by idea: ``format`` (version, keys, caps, commands, records), ``paths`` (where a
file goes), ``integrity`` (checksums, signature, estimate digests), ``scenario_text`` (the
scenario and map a file carries), ``reader`` (reading and checking a file).
"""

from __future__ import annotations

from beacon_sim.io.recording.format import (  # noqa: F401
    COMMAND_KINDS,
    FLUSH_EVERY_S,
    FORMAT_NAME,
    FORMAT_VERSION,
    HEADER_KEYS,
    KEY_VARIABLE,
    MAX_COMMANDS,
    MAX_DESCRIPTION_CHARS,
    MAX_LINE_CHARS,
    MAX_NAME_CHARS,
    MAX_RECORDED_TURN,
    MAX_RECORDING_BYTES,
    MODEL_KEYS,
    READ_VERSIONS,
    RECORDINGS_DIR,
    TEAM_COMMAND_KINDS,
    TEAM_KIND,
    VALUES_PER_ROBOT,
    FileParts,
    RecordingError,
    TickRecord,
    check_pose,
    check_toggle,
    dumps,
    validate_command,
)
from beacon_sim.io.recording.integrity import (  # noqa: F401
    EstimateDigests,
    Signer,
    effective_params,
    estimate_bytes,
    estimate_values,
    is_fingerprint,
    recorded_tracks,
    recording_key,
    text_checksum,
)
from beacon_sim.io.recording.paths import (  # noqa: F401
    default_recording_path,
    open_exclusive,
)
from beacon_sim.io.recording.reader import (  # noqa: F401
    Recording,
    last_line,
    load_recording,
)
from beacon_sim.io.recording.scenario_text import (  # noqa: F401
    disk_map_note,
    is_team_header,
    map_file_name,
    map_header,
    rebuild_scenario,
    rebuild_team_scenario,
    recorded_map,
    scenario_folder,
    scenario_label,
    scenario_text,
)
