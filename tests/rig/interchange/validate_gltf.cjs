// Validate a .glb with the Khronos glTF validator; print its report as JSON.
// Usage: node validate_gltf.cjs VALIDATOR_MODULE FILE.glb
const fs = require("fs");
const validator = require(process.argv[2]);
const bytes = new Uint8Array(fs.readFileSync(process.argv[3]));
validator
  .validateBytes(bytes, { maxIssues: 100 })
  .then((report) => console.log(JSON.stringify(report)))
  .catch((error) => {
    console.error(String(error));
    process.exit(1);
  });
