// node-opcua against drivemap's OPC UA server: browse Objects/<gateway>/<device>, read every
// variable (value, DataType, AccessLevel, UserAccessLevel, EngineeringUnits), then try the writes
// given on the command line. Prints one JSON document. Run with cwd = the folder holding node_modules.
//   node opcua_probe.js ENDPOINT GATEWAY '[{"node": "ns=2;s=dev.reg", "type": "UInt16", "value": 5}]'
"use strict";
const opcua = require("node-opcua");

async function children(session, nodeId) {
  const result = await session.browse({
    nodeId, browseDirection: opcua.BrowseDirection.Forward, includeSubtypes: true,
    referenceTypeId: "HierarchicalReferences", resultMask: 63,
  });
  return result.references || [];
}

async function readVariable(session, ref) {
  const nodeId = ref.nodeId.toString();
  const attrs = [opcua.AttributeIds.Value, opcua.AttributeIds.DataType, opcua.AttributeIds.AccessLevel,
                 opcua.AttributeIds.UserAccessLevel];
  const [value, dataType, access, userAccess] = await session.read(attrs.map(a => ({nodeId, attributeId: a})));
  let typeName = null;
  if (dataType.value.value) {
    const name = await session.read({nodeId: dataType.value.value, attributeId: opcua.AttributeIds.BrowseName});
    typeName = name.value.value ? name.value.value.name : null;
  }
  const out = {
    node: nodeId, name: ref.browseName.name, status: value.statusCode.name,
    value: value.value ? value.value.value : null, dataType: typeName,
    variant: value.value ? opcua.DataType[value.value.dataType] : null,
    accessLevel: access.value.value, userAccessLevel: userAccess.value.value, eu: null,
  };
  if (out.value !== null && typeof out.value === "object" && out.value.length !== undefined) {
    out.value = Array.from(out.value);
  }
  if (typeof out.value === "bigint") out.value = out.value.toString();
  if (Array.isArray(out.value) && out.value.length === 2 && typeof out.value[0] === "number" && /Int64/.test(out.variant || "")) {
    out.value = (BigInt(out.value[0]) * 4294967296n + BigInt(out.value[1] >>> 0)).toString();  // node-opcua's [high, low]
  }
  for (const prop of await children(session, ref.nodeId)) {
    if (prop.browseName.name !== "EngineeringUnits") continue;
    const eu = await session.read({nodeId: prop.nodeId, attributeId: opcua.AttributeIds.Value});
    const v = eu.value.value;
    if (v) out.eu = {unitId: v.unitId, namespaceUri: v.namespaceUri, displayName: v.displayName ? v.displayName.text : null};
  }
  return out;
}

async function main() {
  const [endpoint, gateway, writesJson] = process.argv.slice(2);
  const writes = JSON.parse(writesJson || "[]");
  const client = opcua.OPCUAClient.create({
    endpointMustExist: false, securityMode: opcua.MessageSecurityMode.None,
    securityPolicy: opcua.SecurityPolicy.None, connectionStrategy: {maxRetry: 2, initialDelay: 500},
  });
  await client.connect(endpoint);
  const session = await client.createSession();
  const report = {devices: {}, writes: []};
  try {
    const root = (await children(session, "ns=0;i=85")).find(r => r.browseName.name === gateway);
    if (!root) throw new Error(`no ${gateway} under Objects`);
    for (const dev of await children(session, root.nodeId)) {
      const vars = [];
      for (const ref of await children(session, dev.nodeId)) {
        if (ref.nodeClass !== opcua.NodeClass.Variable) continue;
        vars.push(await readVariable(session, ref));
      }
      report.devices[dev.browseName.name] = vars;
    }
    for (const w of writes) {
      const status = await session.write({
        nodeId: w.node, attributeId: opcua.AttributeIds.Value,
        value: {value: {dataType: opcua.DataType[w.type], value: w.value}},
      });
      report.writes.push({node: w.node, status: status.name});
    }
  } finally {
    await session.close();
    await client.disconnect();
  }
  process.stdout.write("\n@@drivemap-report@@" + JSON.stringify(report) + "\n");
}

main().catch(err => { process.stderr.write(String(err && err.stack || err) + "\n"); process.exit(1); });
