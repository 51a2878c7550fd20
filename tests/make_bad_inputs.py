#!/usr/bin/env python3
"""Writes the bad-input catalogue's files into tests/bad_inputs/ (the files are committed; this
script documents how the binary and generated ones were made and regenerates them all).
Each case breaks one thing in a small valid scene of its format; names starting with "ok-" are
variants that must render (BOM, CRLF, a missing MTL library, GLB). Expected outcomes are in
tests/bad_inputs/catalogue.tsv. Fixed seed: the output is the same on every run.

Files named fuzz-* are inputs libFuzzer found crashing the renderer (tests/fuzz), kept verbatim as
regression cases; this script does not write them.

Usage: python3 tests/make_bad_inputs.py
"""
import base64, json, os, struct, random
D = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'bad_inputs')
random.seed(167)
def w(name, data):
    mode = 'wb' if isinstance(data, bytes) else 'w'
    with open(os.path.join(D, name), mode, **({} if mode == 'wb' else {'newline': ''})) as f:
        f.write(data)
garbage = bytes(random.getrandbits(8) for _ in range(512))

# ---------- native JSON ----------
good_json = '''{
  "image": { "width": 32, "height": 24 },
  "camera": { "eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 45 },
  "materials": { "red": { "diffuse": [0.8, 0.1, 0.1], "ambient": 0.1 } },
  "lights": [ { "type": "directional", "direction": [1, 1, 1] } ],
  "nodes": [ { "models": [ { "geometry": { "type": "sphere" }, "material": "red" } ] } ]
}
'''
def replaced(text, a, b):
    """`text` with its first `a` replaced by `b` (which must be there: a case must break something)."""
    assert a in text, a
    return text.replace(a, b, 1)
def jrep(a, b):
    return replaced(good_json, a, b)
w('json-empty.json', '')
w('json-truncated.json', good_json[:len(good_json) // 2])
w('json-binary-garbage.json', garbage)
w('json-top-level-array.json', '[1, 2, 3]\n')
w('json-wrong-type.json', jrep('"width": 32', '"width": "wide"'))
w('json-nan-literal.json', jrep('"fovy": 45', '"fovy": NaN'))
w('json-infinite-number.json', jrep('"eye": [0, 0, 5]', '"eye": [0, 0, 1e999]'))
w('json-zero-width.json', jrep('"width": 32', '"width": 0'))
w('json-negative-height.json', jrep('"height": 24', '"height": -24'))
w('json-huge-image.json', jrep('"width": 32, "height": 24', '"width": 60000, "height": 60000'))
w('json-undefined-material.json', jrep('"material": "red"', '"material": "blue"'))
w('json-negative-radius.json', jrep('{ "type": "sphere" }', '{ "type": "sphere", "radius": -1 }'))
w('json-mesh-index-out-of-range.json', jrep('{ "type": "sphere" }',
  '{ "type": "mesh", "positions": [[0,0,0],[1,0,0],[0,1,0]], "triangles": [[0, 1, 7]] }'))
w('json-missing-obj-file.json', jrep('{ "type": "sphere" }', '{ "type": "obj", "path": "does-not-exist.obj" }'))
w('json-singular-transform.json', jrep('{ "models"', '{ "scale": [1, 0, 1], "models"'))
parts_open = '{ "children": [ ' * 5000
parts_close = ' ] }' * 5000
w('json-deep-nesting.json', jrep('"nodes": [ { "models": [ { "geometry": { "type": "sphere" }, "material": "red" } ] } ]',
  '"nodes": [ ' + parts_open + '{ "models": [ { "geometry": { "type": "sphere" }, "material": "red" } ] }' + parts_close + ' ]'))
w('json-utf16.json', good_json.encode('utf-16'))
w('json-eye-beyond-limit.json', jrep('"eye": [0, 0, 5]', '"eye": [0, 0, 1e20]'))
w('json-vertex-beyond-limit.json', jrep('{ "type": "sphere" }',
  '{ "type": "mesh", "positions": [[0,0,0],[1,0,0],[0,1e30,0]], "triangles": [[0, 1, 2]] }'))
w('ok-json-bom.json', b'\xef\xbb\xbf' + good_json.encode())
w('ok-json-crlf.json', good_json.replace('\n', '\r\n'))

# ---------- CSE167x .test ----------
good_test = '''size 32 24
camera 0 0 5 0 0 0 0 1 0 45
directional 1 1 1 1 1 1
diffuse 0.8 0.1 0.1
maxverts 3
vertex -1 -1 0
vertex 1 -1 0
vertex 0 1 0
tri 0 1 2
sphere 0 0 -1 0.5
'''
def trep(a, b):
    return replaced(good_test, a, b)
w('test-empty.test', '')
w('test-binary-garbage.test', garbage)
w('test-truncated.test', good_test[:good_test.index('tri 0 1 2') + len('tri 0 1')])
w('test-wrong-type.test', trep('size 32 24', 'size abc 24'))
w('test-zero-size.test', trep('size 32 24', 'size 0 0'))
w('test-negative-size.test', trep('size 32 24', 'size -32 24'))
w('test-huge-image.test', trep('size 32 24', 'size 200000 200000'))
w('test-maxverts-huge.test', trep('maxverts 3', 'maxverts 1e12'))
w('test-vertex-index-out-of-range.test', trep('tri 0 1 2', 'tri 0 1 5'))
w('test-more-vertices-than-maxverts.test', trep('vertex 0 1 0', 'vertex 0 1 0\nvertex 0 2 0'))
w('test-nan.test', trep('sphere 0 0 -1 0.5', 'sphere 0 0 -1 nan'))
w('test-infinity.test', trep('vertex 1 -1 0', 'vertex inf -1 0'))
w('test-unknown-command.test', trep('sphere 0 0 -1 0.5', 'cube 0 0 -1 0.5'))
w('test-pop-without-push.test', trep('sphere 0 0 -1 0.5', 'popTransform\nsphere 0 0 -1 0.5'))
w('test-vertex-beyond-limit.test', trep('vertex 0 1 0', 'vertex 0 1e30 0'))
w('test-degenerate-camera.test', trep('camera 0 0 5 0 0 0 0 1 0 45', 'camera 0 0 5 0 0 5 0 1 0 45'))
w('ok-test-bom.test', b'\xef\xbb\xbf' + good_test.encode())
w('ok-test-crlf.test', good_test.replace('\n', '\r\n'))

# ---------- OBJ / MTL ----------
good_obj = '''# one triangle
v -1 -1 0
v 1 -1 0
v 0 1 0
f 1 2 3
'''
def orep(a, b):
    return replaced(good_obj, a, b)
w('obj-empty.obj', '')
w('obj-binary-garbage.obj', garbage)
w('obj-no-faces.obj', '# vertices only\nv 0 0 0\nv 1 0 0\nv 0 1 0\n')
w('obj-index-out-of-range.obj', orep('f 1 2 3', 'f 1 2 9'))
w('obj-index-zero.obj', orep('f 1 2 3', 'f 0 1 2'))
w('obj-negative-index-out-of-range.obj', orep('f 1 2 3', 'f -1 -2 -9'))
w('obj-nan-vertex.obj', orep('v 1 -1 0', 'v nan -1 0'))
w('obj-truncated.obj', good_obj[:good_obj.index('v 0 1 0') + len('v 0 1')] )
w('ok-obj-missing-mtl.obj', 'mtllib does-not-exist.mtl\nusemtl shiny\n' + good_obj)
w('obj-bad-mtl.obj', 'mtllib obj-bad-mtl.mtl\nusemtl broken\n' + good_obj)
w('obj-bad-mtl.mtl', 'newmtl broken\nKd 0.5 nan 0.5\n')
w('ok-obj-bom.obj', b'\xef\xbb\xbf' + good_obj.encode())
w('ok-obj-crlf.obj', good_obj.replace('\n', '\r\n'))

# ---------- glTF / GLB ----------
positions = struct.pack('<9f', -1, -1, 0, 1, -1, 0, 0, 1, 0)
indices = struct.pack('<3H', 0, 1, 2) + b'\0\0'
blob = positions + indices
def gltf_doc(uri=None, count=3, index_max=None, nodes=None, index_bytes=None):
    data = blob if index_bytes is None else positions + index_bytes
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes if nodes is not None else [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(data),
                     "uri": uri if uri is not None else "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
                       "min": [-1, -1, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
    }
    return doc
def dump(doc):
    return json.dumps(doc, indent=1) + '\n'
good_gltf = dump(gltf_doc())
w('gltf-empty.gltf', '')
w('gltf-truncated.gltf', good_gltf[:len(good_gltf) // 2])
w('gltf-binary-garbage.gltf', garbage)
w('gltf-no-asset.gltf', dump({k: v for k, v in gltf_doc().items() if k != 'asset'}))
w('gltf-wrong-type.gltf', dump(dict(gltf_doc(), nodes="all of them")))
w('gltf-accessor-count-beyond-buffer.gltf', dump(gltf_doc(count=1000)))
w('gltf-accessor-count-huge.gltf', dump(gltf_doc(count=4000000000)))
w('gltf-accessor-count-negative.gltf', dump(gltf_doc(count=-3)))
w('gltf-index-out-of-range.gltf', dump(gltf_doc(index_bytes=struct.pack('<3H', 0, 1, 40) + b'\0\0')))
w('gltf-cyclic-nodes.gltf', dump(gltf_doc(nodes=[{"mesh": 0, "children": [1]}, {"children": [0]}])))
w('gltf-node-own-child.gltf', dump(gltf_doc(nodes=[{"mesh": 0, "children": [0]}])))
# A DAG, not a cycle: each level instances the next twice, 2^40 triangles in all.
dag = [{"children": [i + 1, i + 1]} for i in range(40)] + [{"mesh": 0}]
w('gltf-exponential-instancing.gltf', dump(gltf_doc(nodes=dag)))
w('gltf-missing-buffer-file.gltf', dump(gltf_doc(uri="does-not-exist.bin")))
w('gltf-bad-base64.gltf', dump(gltf_doc(uri="data:application/octet-stream;base64,!!!!not base64!!!!")))
w('gltf-singular-scale.gltf', dump(gltf_doc(nodes=[{"mesh": 0, "scale": [1, 0, 1]}])))
w('gltf-node-index-out-of-range.gltf', dump(dict(gltf_doc(), scenes=[{"nodes": [5]}])))
# An image in a bufferView that runs past its buffer: tinygltf 2.7.0 hands the loader a pointer it
# never checked (the fuzzer found the heap overflow).
textured = gltf_doc()
textured["meshes"][0]["primitives"][0]["material"] = 0
textured["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
textured["textures"] = [{"source": 0}]
textured["images"] = [{"bufferView": 2, "mimeType": "image/png"}]
textured["bufferViews"].append({"buffer": 0, "byteOffset": 40, "byteLength": 4333})
w('gltf-image-view-outside-buffer.gltf', dump(textured))
def glb(json_bytes, bin_bytes, total=None, json_len=None):
    json_bytes += b' ' * (-len(json_bytes) % 4)
    bin_bytes += b'\0' * (-len(bin_bytes) % 4)
    body = struct.pack('<II', len(json_bytes) if json_len is None else json_len, 0x4E4F534A) + json_bytes
    body += struct.pack('<II', len(bin_bytes), 0x004E4942) + bin_bytes
    length = 12 + len(body)
    return struct.pack('<III', 0x46546C67, 2, length if total is None else total) + body
glb_doc = gltf_doc()
glb_doc["buffers"] = [{"byteLength": len(blob)}]
glb_json = json.dumps(glb_doc).encode()
good_glb = glb(glb_json, blob)
w('glb-empty.glb', b'')
w('glb-binary-garbage.glb', garbage)
w('glb-truncated.glb', good_glb[:len(good_glb) - 20])
w('glb-bad-magic.glb', b'GLTF' + good_glb[4:])
w('glb-chunk-length-huge.glb', glb(glb_json, blob, json_len=0xFFFFFFF0))
w('glb-header-length-huge.glb', glb(glb_json, blob, total=0xFFFFFFF0))
w('ok-gltf-bom.gltf', b'\xef\xbb\xbf' + good_gltf.encode())
w('ok-gltf-crlf.gltf', good_gltf.replace('\n', '\r\n'))
w('ok-glb.glb', good_glb)
print(len(os.listdir(D)), 'files')
