// An independent OPC UA client for the tests (node-opcua), driven over stdin/stdout: one JSON
// request per line, one JSON answer per line after "@@opcua " ({"id", "ok", "result"} or {"id",
// "ok": false, "error"}). One process serves a whole test module, so node-opcua loads once.
//
// Requests (NodeIds are node-opcua strings, "ns=5;s=m1013.Frame.robot_state"):
//   connect     {name, endpoint, mode: None|Sign|SignAndEncrypt, user?, password?, cert?, key?,
//                applicationUri?, pki}
//   disconnect  {name}
//   namespaces  {name}                          → the server's namespace array
//   browse_tree {name, root}                    → every node under root (hierarchical, forward):
//                path, nodeId, nodeClass, browseName, typeDefinition, referenceType
//   read        {name, nodes}                   → [{value, dataType, status, sourceTimestamp}]
//   write       {name, items: [{node, dataType, value}]} → [status name]
//   call        {name, object, method}          → {status, outputs}
//   monitor     {name, key, nodes, samplingMs, publishingMs} → starts collecting
//   take        {key}                           → the notifications collected since, cleared
//   unmonitor   {key}
"use strict";

const readline = require("readline");
const {
  OPCUAClient,
  OPCUACertificateManager,
  MessageSecurityMode,
  SecurityPolicy,
  AttributeIds,
  BrowseDirection,
  NodeClass,
  ClientSubscription,
  ClientMonitoredItem,
  TimestampsToReturn,
  DataType,
  UserTokenType,
  resolveNodeId,
  makeResultMask,
} = require("node-opcua");

const MARK = "@@opcua ";
// node-opcua writes its own warnings to stdout: answers are the lines that start with MARK.
const sessions = new Map();
const monitors = new Map();

function statusName(statusCode) {
  return statusCode && statusCode.name ? statusCode.name : String(statusCode);
}

function plain(value) {
  if (value === null || value === undefined) return null;
  if (typeof value === "bigint") return Number(value);
  if (Array.isArray(value) || ArrayBuffer.isView(value)) return Array.from(value, plain);
  if (value instanceof Date) return value.getTime();
  if (typeof value === "object") {
    if (typeof value.text === "string" || value.text === null) return value.text; // LocalizedText
    if (typeof value.toJSON === "function") return value.toJSON();
    return String(value);
  }
  return value;
}

function dataValue(dv) {
  return {
    value: dv.value ? plain(dv.value.value) : null,
    dataType: dv.value ? DataType[dv.value.dataType] : null,
    status: statusName(dv.statusCode),
    sourceTimestamp: dv.sourceTimestamp ? dv.sourceTimestamp.getTime() : null,
    sourcePicoseconds: dv.sourcePicoseconds || 0,
  };
}

async function connect(request) {
  const mode = MessageSecurityMode[request.mode || "None"];
  const policy = request.mode && request.mode !== "None" ? SecurityPolicy.Basic256Sha256 : SecurityPolicy.None;
  const certificateManager = new OPCUACertificateManager({
    rootFolder: request.pki,
    automaticallyAcceptUnknownCertificate: true,
  });
  const options = {
    applicationName: "cobot-hmi tests",
    securityMode: mode,
    securityPolicy: policy,
    endpointMustExist: true,
    connectionStrategy: { maxRetry: 0, initialDelay: 100, maxDelay: 200 },
    clientCertificateManager: certificateManager,
    requestedSessionTimeout: 60000,
  };
  if (request.applicationUri) options.applicationUri = request.applicationUri;
  if (request.cert) options.certificateFile = request.cert;
  if (request.key) options.privateKeyFile = request.key;
  const client = OPCUAClient.create(options);
  let session;
  try {
    await client.connect(request.endpoint);
    const identity = request.user
      ? { type: UserTokenType.UserName, userName: request.user, password: request.password }
      : { type: UserTokenType.Anonymous };
    session = await client.createSession(identity);
  } catch (error) {
    await client.disconnect().catch(() => {});
    throw error;
  }
  sessions.set(request.name, { client, session });
  return { sessionId: session.sessionId.toString() };
}

function sessionOf(name) {
  const entry = sessions.get(name);
  if (!entry) throw new Error(`no session ${name}`);
  return entry.session;
}

async function browseTree(request) {
  const session = sessionOf(request.name);
  const out = [];
  const queue = [{ nodeId: resolveNodeId(request.root), path: "" }];
  const seen = new Set();
  while (queue.length) {
    const batch = queue.splice(0, 50);
    const results = await session.browse(
      batch.map((item) => ({
        nodeId: item.nodeId,
        referenceTypeId: "HierarchicalReferences",
        includeSubtypes: true,
        browseDirection: BrowseDirection.Forward,
        nodeClassMask: 0,
        resultMask: makeResultMask("ReferenceType | IsForward | BrowseName | NodeClass | TypeDefinition"),
      })),
    );
    for (let i = 0; i < batch.length; i++) {
      const parent = batch[i];
      for (const reference of results[i].references || []) {
        const id = reference.nodeId.toString();
        const path = `${parent.path}/${reference.browseName.namespaceIndex}:${reference.browseName.name}`;
        out.push({
          path,
          nodeId: id,
          nodeClass: NodeClass[reference.nodeClass],
          browseName: { ns: reference.browseName.namespaceIndex, name: reference.browseName.name },
          typeDefinition: reference.typeDefinition ? reference.typeDefinition.toString() : null,
          referenceType: reference.referenceTypeId.toString(),
        });
        if (!seen.has(id) && reference.nodeClass !== NodeClass.Method) {
          seen.add(id);
          queue.push({ nodeId: reference.nodeId, path });
        }
      }
    }
  }
  return out;
}

async function read(request) {
  const session = sessionOf(request.name);
  const values = await session.read(
    request.nodes.map((node) => ({ nodeId: node, attributeId: AttributeIds.Value })),
    0,
  );
  return values.map(dataValue);
}

async function write(request) {
  const session = sessionOf(request.name);
  const statuses = await session.write(
    request.items.map((item) => ({
      nodeId: item.node,
      attributeId: AttributeIds.Value,
      value: { value: { dataType: DataType[item.dataType], value: item.value } },
    })),
  );
  return statuses.map(statusName);
}

async function call(request) {
  const session = sessionOf(request.name);
  const result = await session.call({ objectId: request.object, methodId: request.method, inputArguments: [] });
  return {
    status: statusName(result.statusCode),
    outputs: (result.outputArguments || []).map((variant) => plain(variant.value)),
  };
}

async function monitor(request) {
  const session = sessionOf(request.name);
  const subscription = ClientSubscription.create(session, {
    requestedPublishingInterval: request.publishingMs || request.samplingMs,
    requestedLifetimeCount: 600,
    requestedMaxKeepAliveCount: 20,
    maxNotificationsPerPublish: 0,
    publishingEnabled: true,
    priority: 1,
  });
  const collected = [];
  const items = [];
  for (const node of request.nodes) {
    const item = ClientMonitoredItem.create(
      subscription,
      { nodeId: node, attributeId: AttributeIds.Value },
      { samplingInterval: request.samplingMs, discardOldest: true, queueSize: 10 },
      TimestampsToReturn.Both,
    );
    item.on("changed", (dv) => collected.push({ node, receivedAt: Date.now(), ...dataValue(dv) }));
    items.push(item);
  }
  await new Promise((resolve) => subscription.once("started", resolve));
  monitors.set(request.key, { subscription, collected });
  return { items: items.length };
}

async function take(request) {
  const entry = monitors.get(request.key);
  if (!entry) throw new Error(`no monitor ${request.key}`);
  return entry.collected.splice(0, entry.collected.length);
}

async function unmonitor(request) {
  const entry = monitors.get(request.key);
  if (entry) {
    monitors.delete(request.key);
    await entry.subscription.terminate();
  }
  return {};
}

async function disconnect(request) {
  const entry = sessions.get(request.name);
  if (entry) {
    sessions.delete(request.name);
    await entry.session.close().catch(() => {});
    await entry.client.disconnect();
  }
  return {};
}

const OPS = {
  connect,
  disconnect,
  namespaces: async (request) => {
    const session = sessionOf(request.name);
    const value = await session.read({ nodeId: "i=2255", attributeId: AttributeIds.Value });
    return plain(value.value.value);
  },
  browse_tree: browseTree,
  read,
  write,
  call,
  monitor,
  take,
  unmonitor,
};

const lines = readline.createInterface({ input: process.stdin });
lines.on("line", async (line) => {
  let request;
  try {
    request = JSON.parse(line);
    const op = OPS[request.op];
    if (!op) throw new Error(`unknown op ${request.op}`);
    const result = await op(request);
    process.stdout.write(MARK + JSON.stringify({ id: request.id, ok: true, result }) + "\n");
  } catch (error) {
    const id = request ? request.id : null;
    process.stdout.write(MARK + JSON.stringify({ id, ok: false, error: String(error && error.message ? error.message : error) }) + "\n");
  }
});
lines.on("close", async () => {
  for (const name of Array.from(sessions.keys())) await disconnect({ name }).catch(() => {});
  process.exit(0);
});
