"""Each part of the service is given its own settings, never the whole: the recorder its
``HistorySettings``, a robot its ``RobotSettings``, its connection's, the ``WebSettings`` and the
``AlarmLimitSettings``, the directory its ``DirectorySettings`` (the composed settings hold each
as a part of their own, values as loaded)."""

from __future__ import annotations

from pathlib import Path

from cobot_hmi.scanner.originator import OriginatorSettings
from cobot_hmi.service.access.directory_settings import DirectorySettings
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.recording.history_settings import HistorySettings
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.service_settings import ServiceSettings
from cobot_hmi.service.web.web_settings import WebSettings


def _settings(tmp_path: Path) -> ServiceSettings:
    return load_settings(
        {"robot_host": "127.0.0.1", "history_flush_s": 0.25},
        environ={"COBOT_HMI_ALARM_SHELVE_MAX_HIGH_S": "120", "COBOT_HMI_WS_BATCH_MS": "20"},
        config_file=None,
    ).replace(state_dir=tmp_path)


def test_a_part_is_its_own_object_with_the_loaded_values(tmp_path: Path) -> None:
    settings = _settings(tmp_path)
    history = settings.recording
    assert type(history) is HistorySettings
    assert set(history.model_dump()) == set(HistorySettings.model_fields)
    assert history.history_flush_s == 0.25
    assert history.model_fields_set == {"history_flush_s"}
    alarms = settings.alarm_limits
    assert alarms.alarm_shelve_max_high_s == 120
    assert not hasattr(alarms, "history_flush_s")


def test_the_service_gives_each_part_only_its_settings(tmp_path: Path) -> None:
    service = Service(_settings(tmp_path))
    assert service.recorder is not None
    assert type(service.recorder.settings) is HistorySettings
    assert service.recorder.settings.history_flush_s == 0.25
    assert service.recorder.root == tmp_path / "history"
    robot = service.default_robot
    assert robot.settings.host == "127.0.0.1"
    assert isinstance(robot.link.settings, OriginatorSettings)
    assert sorted(robot.alarms.shelving.max_by_priority_s.values())[0] == 120  # high's
    assert robot.hub.batch_s == 0.02
    assert service.directory is None  # no ldap_url: no directory
    with_directory = Service(
        _settings(tmp_path).replace(
            ldap_url="ldap://127.0.0.1:1",
            ldap_user_dn="uid={user}",
            ldap_group_role={"cn=operators": "operator"},
        )
    )
    assert type(with_directory.directory.settings) is DirectorySettings  # type: ignore[union-attr]
    assert not isinstance(service.recorder.settings, WebSettings)
