-- The service's database as the code at 5606929 wrote it (backend/tests/legacy/make_legacy.py; sqlite3 iterdump).
BEGIN TRANSACTION;
CREATE TABLE audit (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    user TEXT,
    client TEXT,
    action TEXT NOT NULL,
    fields TEXT NOT NULL,
    before TEXT,
    requested TEXT,
    outcome TEXT NOT NULL,
    reason TEXT
, robot TEXT, origin TEXT);
INSERT INTO "audit" VALUES(1,1700000000.0,'alice','127.0.0.9','control.take','[]','null','null','granted',NULL,'left','PATCH /api/v1/robots/left/command');
INSERT INTO "audit" VALUES(2,1700000001.0,'alice','127.0.0.9','write','["controlbox_do.2"]','[false]','[true]','confirmed',NULL,'left','PATCH /api/v1/robots/left/command');
INSERT INTO "audit" VALUES(3,1700000002.0,NULL,'127.0.0.9','write','["analog_output.0"]','null','null','invalid','AO 0 is at most 10 V',NULL,NULL);
CREATE TABLE events (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    kind TEXT NOT NULL,
    data TEXT NOT NULL
, robot TEXT);
INSERT INTO "events" VALUES(1,1700000003.0,'flag','{"flag":"servo_on","value":true}','left');
INSERT INTO "events" VALUES(2,1700000004.0,'robot_state','{"state":1,"name":"STANDBY"}',NULL);
CREATE INDEX events_kind ON events (kind, id);
CREATE INDEX events_robot ON events (robot, id);
CREATE INDEX audit_robot ON audit (robot, id);
DELETE FROM "sqlite_sequence";
INSERT INTO "sqlite_sequence" VALUES('audit',3);
INSERT INTO "sqlite_sequence" VALUES('events',2);
COMMIT;
