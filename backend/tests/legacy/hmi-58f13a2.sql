-- The service's database as the code at 58f13a2 wrote it (backend/tests/legacy/make_legacy.py; sqlite3 iterdump).
BEGIN TRANSACTION;
CREATE TABLE alarm_history (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    robot TEXT NOT NULL,
    alarm_id TEXT NOT NULL,
    key TEXT NOT NULL,
    name TEXT NOT NULL,
    priority TEXT NOT NULL,
    transition TEXT NOT NULL,
    state TEXT NOT NULL,
    shelved INTEGER NOT NULL,
    message TEXT,
    value TEXT,
    label TEXT,
    tag TEXT,
    user TEXT,
    comment TEXT
);
INSERT INTO "alarm_history" VALUES(1,1.79576932182264256479e+09,'m1013','m1013:emergency_stop','emergency_stop','Emergency stop','critical','activated','active_unacknowledged',0,'robot state EMERGENCY_STOP, emergency_stopped set','0',NULL,NULL,NULL,NULL);
INSERT INTO "alarm_history" VALUES(2,1.79576932210201525687e+09,'m1013','m1013:emergency_stop','emergency_stop','Emergency stop','critical','acknowledged','active_acknowledged',0,'robot state EMERGENCY_STOP, emergency_stopped set','0',NULL,NULL,'olivia','checked the cell');
INSERT INTO "alarm_history" VALUES(3,1.79576932219263529777e+09,'m1013','m1013:emergency_stop','emergency_stop','Emergency stop','critical','cleared','normal',0,'robot state 2','2',NULL,NULL,NULL,NULL);
INSERT INTO "alarm_history" VALUES(4,1.79576932219263529777e+09,'m1013','m1013:safe_off','safe_off','Servo off after an error (SAFE_OFF)','high','activated','active_unacknowledged',0,'robot state SAFE_OFF','2',NULL,NULL,NULL,NULL);
INSERT INTO "alarm_history" VALUES(5,1.79576932269264674191e+09,'m1013','m1013:safe_off','safe_off','Servo off after an error (SAFE_OFF)','high','cleared','returned_unacknowledged',0,'robot state 13','13',NULL,NULL,NULL,NULL);
INSERT INTO "alarm_history" VALUES(6,1.7957693227726306915e+09,'m1013','m1013:protective_stop','protective_stop','Protective stop','high','activated','active_unacknowledged',0,'robot state INTERRUPTED, safety_stopped set','3',NULL,NULL,NULL,NULL);
INSERT INTO "alarm_history" VALUES(7,1.79576932296738052364e+09,'m1013','m1013:protective_stop','protective_stop','Protective stop','high','shelved','active_unacknowledged',1,'robot state INTERRUPTED, safety_stopped set','3',NULL,NULL,'olivia','maintenance');
CREATE TABLE alarm_state (
    id TEXT PRIMARY KEY,
    robot TEXT NOT NULL,
    key TEXT NOT NULL,
    data TEXT NOT NULL,
    time REAL NOT NULL
);
INSERT INTO "alarm_state" VALUES('m1013:emergency_stop','m1013','emergency_stop','{"state":"normal","changed_at":1795769322.1926353,"activated_at":1795769321.8226426,"cleared_at":1795769322.1926353,"acknowledged_at":1795769322.1020153,"acknowledged_by":"olivia","ack_comment":"checked the cell","shelved_until":null,"shelved_by":null,"shelve_reason":null,"value":2,"message":"robot state 2"}',1.79576932219263529777e+09);
INSERT INTO "alarm_state" VALUES('m1013:safe_off','m1013','safe_off','{"state":"returned_unacknowledged","changed_at":1795769322.6926467,"activated_at":1795769322.1926353,"cleared_at":1795769322.6926467,"acknowledged_at":null,"acknowledged_by":null,"ack_comment":null,"shelved_until":null,"shelved_by":null,"shelve_reason":null,"value":13,"message":"robot state 13"}',1.79576932269264674191e+09);
INSERT INTO "alarm_state" VALUES('m1013:protective_stop','m1013','protective_stop','{"state":"active_unacknowledged","changed_at":1795769322.9673805,"activated_at":1795769322.7726307,"cleared_at":null,"acknowledged_at":null,"acknowledged_by":null,"ack_comment":null,"shelved_until":1795772922.9673805,"shelved_by":"olivia","shelve_reason":"maintenance","value":3,"message":"robot state INTERRUPTED, safety_stopped set"}',1.79576932296738052364e+09);
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
, robot TEXT, origin TEXT, summary TEXT, tags TEXT);
INSERT INTO "audit" VALUES(1,1.79576932148317456247e+09,'ada','127.0.0.1','tags.update','["controlbox_do.2","bit_input_registers.40"]','null','{"how":"json","before":{"controlbox_do.2":null,"bit_input_registers.40":null},"after":{"controlbox_do.2":"gripper close","bit_input_registers.40":"part ready"}}','updated',NULL,'m1013','PUT /api/v1/robots/m1013/tags','DO 3 = ''gripper close''; Register 40 = ''part ready''','{"controlbox_do.2":"gripper close","bit_input_registers.40":"part ready"}');
INSERT INTO "audit" VALUES(2,1.79576932152765154837e+09,'olivia','127.0.0.1','control.take','[]','null','null','granted',NULL,'m1013',NULL,NULL,NULL);
INSERT INTO "audit" VALUES(3,1.7957693215581550598e+09,'olivia','127.0.0.1','write','["controlbox_do.2"]','{"controlbox_do.2":false}','{"controlbox_do.2":true}','confirmed',NULL,'m1013','PATCH /api/v1/robots/m1013/command','DO 3 (gripper close) = on','{"controlbox_do.2":"gripper close"}');
INSERT INTO "audit" VALUES(4,1.79576932158158731464e+09,'olivia','127.0.0.1','write','["analog_output.0"]','null','{"analog_output":{"0":99}}','invalid','analog_output[0]: 99.0 is outside 4–20 mA (current)','m1013','PATCH /api/v1/robots/m1013/command',NULL,NULL);
INSERT INTO "audit" VALUES(5,1.79576932211226820944e+09,'olivia','127.0.0.1','alarm.ack','["emergency_stop"]','null','{"comment":"checked the cell"}','acknowledged',NULL,'m1013','POST /api/v1/alarms/m1013:emergency_stop/ack','Emergency stop: acknowledged — checked the cell',NULL);
INSERT INTO "audit" VALUES(6,1.79576932300207877161e+09,'olivia','127.0.0.1','alarm.shelve','["protective_stop"]','null','{"reason":"maintenance","duration_s":3600.0}','shelved',NULL,'m1013','POST /api/v1/alarms/m1013:protective_stop/shelve','Protective stop: shelved for 3600 s — maintenance',NULL);
INSERT INTO "audit" VALUES(7,1.79576932304324841504e+09,'olivia','127.0.0.1','control.release','[]','null','null','released','released','m1013',NULL,NULL,NULL);
CREATE TABLE events (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    kind TEXT NOT NULL,
    data TEXT NOT NULL
, robot TEXT);
INSERT INTO "events" VALUES(1,1.79576931838919758794e+09,'connection','{"state":"connecting","reason":null}','m1013');
INSERT INTO "events" VALUES(2,1.79576931843440485e+09,'connection','{"state":"connected","reason":null}','m1013');
INSERT INTO "events" VALUES(3,1.79576931842679715159e+09,'robot_state','{"from":null,"to":1,"from_name":null,"to_name":"INITIALIZING"}','m1013');
INSERT INTO "events" VALUES(4,1.79576932042263865468e+09,'robot_state','{"from":1,"to":13,"from_name":"INITIALIZING","to_name":"STANDALONE_STANDBY"}','m1013');
INSERT INTO "events" VALUES(5,1.79576932042263865468e+09,'flag','{"flag":"servo_on","value":true,"label":"Servo on"}','m1013');
INSERT INTO "events" VALUES(6,1.79576932143263626098e+09,'robot_state','{"from":13,"to":14,"from_name":"STANDALONE_STANDBY","to_name":"STANDALONE_RUNNING"}','m1013');
INSERT INTO "events" VALUES(7,1.79576932153278923031e+09,'control','{"holder":{"user":"olivia","since":1795769321.526434,"session":"6f3a127e580d9d08"},"reason":"taken"}','m1013');
INSERT INTO "events" VALUES(8,1.79576932157424521449e+09,'write','{"user":"olivia","fields":["controlbox_do.2"],"outcome":"confirmed","reason":null,"values":{"controlbox_do.2":true},"labels":{"controlbox_do.2":"DO 3"},"tags":{"controlbox_do.2":"gripper close"},"summary":"DO 3 (gripper close) = on"}','m1013');
INSERT INTO "events" VALUES(9,1.79576932182264256479e+09,'robot_state','{"from":14,"to":0,"from_name":"STANDALONE_RUNNING","to_name":"EMERGENCY_STOP"}','m1013');
INSERT INTO "events" VALUES(10,1.79576932182264256479e+09,'flag','{"flag":"servo_on","value":false,"label":"Servo on"}','m1013');
INSERT INTO "events" VALUES(11,1.79576932182264256479e+09,'flag','{"flag":"emergency_stopped","value":true,"label":"Emergency stopped"}','m1013');
INSERT INTO "events" VALUES(12,1.79576932182264256479e+09,'alarm','{"transition":"activated","user":null,"comment":null,"alarm":{"id":"m1013:emergency_stop","robot":"m1013","key":"emergency_stop","name":"Emergency stop","description":"EMERGENCY_STOP (0): The emergency stop state.","priority":"critical","priority_rank":0,"colour":"red","kind":"state","element":null,"label":null,"tag":null,"unit":"","high":null,"low":null,"active":true,"acknowledged":false,"shelved":false,"state":"active_unacknowledged","changed_at":1795769321.8226426,"activated_at":1795769321.8226426,"cleared_at":null,"acknowledged_at":null,"acknowledged_by":null,"ack_comment":null,"shelved_until":null,"shelved_by":null,"shelve_reason":null,"value":0,"message":"robot state EMERGENCY_STOP, emergency_stopped set"}}','m1013');
INSERT INTO "events" VALUES(13,1.79576932210201525687e+09,'alarm','{"transition":"acknowledged","user":"olivia","comment":"checked the cell","alarm":{"id":"m1013:emergency_stop","robot":"m1013","key":"emergency_stop","name":"Emergency stop","description":"EMERGENCY_STOP (0): The emergency stop state.","priority":"critical","priority_rank":0,"colour":"red","kind":"state","element":null,"label":null,"tag":null,"unit":"","high":null,"low":null,"active":true,"acknowledged":true,"shelved":false,"state":"active_acknowledged","changed_at":1795769322.1020153,"activated_at":1795769321.8226426,"cleared_at":null,"acknowledged_at":1795769322.1020153,"acknowledged_by":"olivia","ack_comment":"checked the cell","shelved_until":null,"shelved_by":null,"shelve_reason":null,"value":0,"message":"robot state EMERGENCY_STOP, emergency_stopped set"}}','m1013');
INSERT INTO "events" VALUES(14,1.79576932219263529777e+09,'robot_state','{"from":0,"to":2,"from_name":"EMERGENCY_STOP","to_name":"SAFE_OFF"}','m1013');
INSERT INTO "events" VALUES(15,1.79576932219263529777e+09,'flag','{"flag":"emergency_stopped","value":false,"label":"Emergency stopped"}','m1013');
INSERT INTO "events" VALUES(16,1.79576932219263529777e+09,'alarm','{"transition":"cleared","user":null,"comment":null,"alarm":{"id":"m1013:emergency_stop","robot":"m1013","key":"emergency_stop","name":"Emergency stop","description":"EMERGENCY_STOP (0): The emergency stop state.","priority":"critical","priority_rank":0,"colour":"red","kind":"state","element":null,"label":null,"tag":null,"unit":"","high":null,"low":null,"active":false,"acknowledged":true,"shelved":false,"state":"normal","changed_at":1795769322.1926353,"activated_at":1795769321.8226426,"cleared_at":1795769322.1926353,"acknowledged_at":1795769322.1020153,"acknowledged_by":"olivia","ack_comment":"checked the cell","shelved_until":null,"shelved_by":null,"shelve_reason":null,"value":2,"message":"robot state 2"}}','m1013');
INSERT INTO "events" VALUES(17,1.79576932219263529777e+09,'alarm','{"transition":"activated","user":null,"comment":null,"alarm":{"id":"m1013:safe_off","robot":"m1013","key":"safe_off","name":"Servo off after an error (SAFE_OFF)","description":"SAFE_OFF (2): The servo off state. This is robot stop state due to a function error or operation error.","priority":"high","priority_rank":1,"colour":"red","kind":"state","element":null,"label":null,"tag":null,"unit":"","high":null,"low":null,"active":true,"acknowledged":false,"shelved":false,"state":"active_unacknowledged","changed_at":1795769322.1926353,"activated_at":1795769322.1926353,"cleared_at":null,"acknowledged_at":null,"acknowledged_by":null,"ack_comment":null,"shelved_until":null,"shelved_by":null,"shelve_reason":null,"value":2,"message":"robot state SAFE_OFF"}}','m1013');
INSERT INTO "events" VALUES(18,1.79576932269264674191e+09,'robot_state','{"from":2,"to":13,"from_name":"SAFE_OFF","to_name":"STANDALONE_STANDBY"}','m1013');
INSERT INTO "events" VALUES(19,1.79576932269264674191e+09,'flag','{"flag":"servo_on","value":true,"label":"Servo on"}','m1013');
INSERT INTO "events" VALUES(20,1.79576932269264674191e+09,'alarm','{"transition":"cleared","user":null,"comment":null,"alarm":{"id":"m1013:safe_off","robot":"m1013","key":"safe_off","name":"Servo off after an error (SAFE_OFF)","description":"SAFE_OFF (2): The servo off state. This is robot stop state due to a function error or operation error.","priority":"high","priority_rank":1,"colour":"red","kind":"state","element":null,"label":null,"tag":null,"unit":"","high":null,"low":null,"active":false,"acknowledged":false,"shelved":false,"state":"returned_unacknowledged","changed_at":1795769322.6926467,"activated_at":1795769322.1926353,"cleared_at":1795769322.6926467,"acknowledged_at":null,"acknowledged_by":null,"ack_comment":null,"shelved_until":null,"shelved_by":null,"shelve_reason":null,"value":13,"message":"robot state 13"}}','m1013');
INSERT INTO "events" VALUES(21,1.7957693227726306915e+09,'robot_state','{"from":13,"to":3,"from_name":"STANDALONE_STANDBY","to_name":"INTERRUPTED"}','m1013');
INSERT INTO "events" VALUES(22,1.7957693227726306915e+09,'flag','{"flag":"safety_stopped","value":true,"label":"Safety stopped"}','m1013');
INSERT INTO "events" VALUES(23,1.7957693227726306915e+09,'alarm','{"transition":"activated","user":null,"comment":null,"alarm":{"id":"m1013:protective_stop","robot":"m1013","key":"protective_stop","name":"Protective stop","description":"INTERRUPTED (3): The system is in a protective stop state due to protective stop input, exceeding the safety threshold, etc.","priority":"high","priority_rank":1,"colour":"yellow","kind":"state","element":null,"label":null,"tag":null,"unit":"","high":null,"low":null,"active":true,"acknowledged":false,"shelved":false,"state":"active_unacknowledged","changed_at":1795769322.7726307,"activated_at":1795769322.7726307,"cleared_at":null,"acknowledged_at":null,"acknowledged_by":null,"ack_comment":null,"shelved_until":null,"shelved_by":null,"shelve_reason":null,"value":3,"message":"robot state INTERRUPTED, safety_stopped set"}}','m1013');
INSERT INTO "events" VALUES(24,1.79576932296738052364e+09,'alarm','{"transition":"shelved","user":"olivia","comment":"maintenance","alarm":{"id":"m1013:protective_stop","robot":"m1013","key":"protective_stop","name":"Protective stop","description":"INTERRUPTED (3): The system is in a protective stop state due to protective stop input, exceeding the safety threshold, etc.","priority":"high","priority_rank":1,"colour":"yellow","kind":"state","element":null,"label":null,"tag":null,"unit":"","high":null,"low":null,"active":true,"acknowledged":false,"shelved":true,"state":"active_unacknowledged","changed_at":1795769322.9673805,"activated_at":1795769322.7726307,"cleared_at":null,"acknowledged_at":null,"acknowledged_by":null,"ack_comment":null,"shelved_until":1795772922.9673805,"shelved_by":"olivia","shelve_reason":"maintenance","value":3,"message":"robot state INTERRUPTED, safety_stopped set"}}','m1013');
INSERT INTO "events" VALUES(25,1.79576932304875755311e+09,'control','{"holder":null,"reason":"released"}','m1013');
INSERT INTO "events" VALUES(26,1.79576932337527728081e+09,'connection','{"state":"idle","reason":null}','m1013');
CREATE TABLE tags (
    robot TEXT NOT NULL,
    key TEXT NOT NULL,
    name TEXT NOT NULL,
    PRIMARY KEY (robot, key)
);
INSERT INTO "tags" VALUES('m1013','controlbox_do.2','gripper close');
INSERT INTO "tags" VALUES('m1013','bit_input_registers.40','part ready');
CREATE INDEX events_kind ON events (kind, id);
CREATE INDEX events_robot ON events (robot, id);
CREATE INDEX audit_robot ON audit (robot, id);
CREATE INDEX alarm_history_robot ON alarm_history (robot, id);
DELETE FROM "sqlite_sequence";
INSERT INTO "sqlite_sequence" VALUES('events',26);
INSERT INTO "sqlite_sequence" VALUES('audit',7);
INSERT INTO "sqlite_sequence" VALUES('alarm_history',7);
COMMIT;
