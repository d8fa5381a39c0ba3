// Every tileset JSON of an export against the 3D Tiles 1.1 JSON schema (JSON Schema 2020-12, ajv). The
// schema files in ./schema are vendored unchanged from github.com/CesiumGS/3d-tiles (specification/schema at
// 390f7665d4c2a2015d794e218c6af3bbea44f9a6), © Cesium GS, Inc., licensed CC BY 4.0 (schema/NOTICE.md).
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import Ajv2020 from 'ajv/dist/2020.js';
import addFormats from 'ajv-formats';

const SCHEMA_DIR = path.join(path.dirname(fileURLToPath(import.meta.url)), 'schema');

function schemaFiles(dir, out = []) {
  for (const e of fs.readdirSync(dir, { withFileTypes: true })) {
    const p = path.join(dir, e.name);
    if (e.isDirectory()) schemaFiles(p, out);
    else if (e.name.endsWith('.schema.json')) out.push(p);
  }
  return out;
}

let validateTileset = null;
function compile() {
  const ajv = new Ajv2020({ allErrors: true, strict: false });
  addFormats(ajv);
  // IRIs (RFC 3987) are not among ajv-formats'; the tileset's URIs are checked for resolving elsewhere.
  ajv.addFormat('iri-reference', true);
  ajv.addFormat('iri', true);
  // Schemas refer to each other by relative path ("./common/rootProperty.schema.json"): give each its
  // path under schema/ as $id, so relative references resolve as files do.
  for (const f of schemaFiles(SCHEMA_DIR)) {
    const s = JSON.parse(fs.readFileSync(f, 'utf8'));
    s.$id = `https://atlastree.invalid/3dtiles/${path.relative(SCHEMA_DIR, f).split(path.sep).join('/')}`;
    ajv.addSchema(s);
  }
  return ajv.getSchema('https://atlastree.invalid/3dtiles/tileset.schema.json');
}

/** The schema errors of one tileset JSON object: [{ where, message }]. */
export function schemaErrors(json) {
  validateTileset ??= compile();
  if (validateTileset(json)) return [];
  return validateTileset.errors.map((e) => ({ where: e.instancePath || '/', message: `${e.message} (${e.schemaPath})` }));
}
