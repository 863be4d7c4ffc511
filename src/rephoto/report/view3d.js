// rephoto's 3D view (see view3d.h): the model coloured by the projected error, the cameras as
// frusta, orbit/zoom, picking. Needs THREE (three.js r111) and THREE.OrbitControls.
(function () {
  'use strict';
  var registry = window.rephotoView = window.rephotoView || {views: {}};

  // core/colormap.cc JetColor: each channel a trapezoid, clamp(1.5 - |4t - c|, 0, 1).
  function jet(t) {
    t = Math.min(1, Math.max(0, t));
    function ramp(c) { return Math.min(1, Math.max(0, 1.5 - Math.abs(4 * t - c))); }
    return [ramp(3), ramp(2), ramp(1)];
  }
  function fmt(v) {
    if (v === null || v === undefined || !isFinite(v)) return '\u2013';
    var a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(2);
    return String(Number(v.toPrecision(4)));
  }
  function esc(s) {
    return String(s).replace(/[&<>"']/g, function (c) {
      return {'&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;'}[c];
    });
  }
  function decode(b64, Type) {
    var bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }
  var FOLD_COLOURS = [0x1f77b4, 0xff7f0e, 0x2ca02c, 0xd62728, 0x9467bd, 0x8c564b, 0xe377c2,
                      0x17becf, 0xbcbd22, 0x7f7f7f];
  var TEST_COLOUR = 0xff7f0e, TRAIN_COLOUR = 0x1f77b4, OTHER_COLOUR = 0x9a9a9a;
  var SUGGESTED_COLOUR = 0xe0119d;

  // The surface shader: mode 0 error (unlit jet of the interpolated error, grey where unseen),
  // 1 model colour (headlight), 2 unseen (magenta) vs seen (light grey), headlight.
  var VERTEX = [
    'attribute float err;', 'attribute float seen;', 'attribute vec3 rgb;', 'attribute float hole;',
    'uniform float pointSize;',
    'varying float vErr;', 'varying float vSeen;', 'varying vec3 vRgb;', 'varying float vHole;',
    'varying vec3 vView;',
    'void main() {',
    '  vErr = err; vSeen = seen; vRgb = rgb; vHole = hole;',
    '  vec4 mv = modelViewMatrix * vec4(position, 1.0);',
    '  vView = mv.xyz;',
    '  gl_PointSize = pointSize;',
    '  gl_Position = projectionMatrix * mv;',
    '}'].join('\n');
  var FRAGMENT = [
    'uniform float mode;', 'uniform float low;', 'uniform float high;', 'uniform float isMesh;',
    'varying float vErr;', 'varying float vSeen;', 'varying vec3 vRgb;', 'varying float vHole;',
    'varying vec3 vView;',
    'float ramp(float t, float c) { return clamp(1.5 - abs(4.0 * t - c), 0.0, 1.0); }',
    'void main() {',
    '  float shade = 1.0;',
    '  if (isMesh > 0.5) {',
    '    vec3 n = normalize(cross(dFdx(vView), dFdy(vView)));',
    '    shade = 0.35 + 0.65 * abs(dot(n, normalize(-vView)));',
    '  }',
    '  vec3 c;',
    '  if (mode < 0.5) {',
    '    if (vSeen < 0.5) { c = vec3(0.5019608); }',
    '    else {',
    '      float t = high != low ? (vErr - low) / (high - low) : 0.0;',
    '      t = clamp(t, 0.0, 1.0);',
    '      c = vec3(ramp(t, 3.0), ramp(t, 2.0), ramp(t, 1.0));',
    '    }',
    '  } else if (mode < 1.5) { c = vRgb * shade; }',
    '  else { c = (vHole > 0.5 ? vec3(0.88, 0.07, 0.62) : vec3(0.86)) * shade; }',
    '  gl_FragColor = vec4(c, 1.0);',
    '}'].join('\n');

  function View(root, data) {
    var self = this;
    this.root = root;
    this.data = data;
    this.mode = data.mode || 'error';
    this.fold = -1;
    this.modelIndex = 0;
    this.frusta = [];
    var host = root.querySelector('.v3-canvas');
    var renderer = new THREE.WebGLRenderer({antialias: false, preserveDrawingBuffer: true});
    renderer.setPixelRatio(1);
    renderer.setClearColor(0xffffff, 1);
    host.appendChild(renderer.domElement);
    this.renderer = renderer;
    this.host = host;
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.01, 100);
    this.controls = new THREE.OrbitControls(this.camera, renderer.domElement);
    this.controls.addEventListener('change', function () { self.render(); });
    this.frustumGroup = new THREE.Group();
    this.scene.add(this.frustumGroup);

    var select = root.querySelector('.v3-model');
    data.models.forEach(function (m, i) {
      var o = document.createElement('option');
      o.value = String(i);
      o.textContent = m.label;
      select.appendChild(o);
    });
    if (data.models.length < 2) root.querySelector('.v3-model-label').style.display = 'none';
    select.addEventListener('change', function () { self.select(Number(select.value)); });
    root.querySelectorAll('.v3-modes button').forEach(function (b) {
      b.addEventListener('click', function () { self.setMode(b.getAttribute('data-mode')); });
    });
    var foldSelect = root.querySelector('.v3-fold');
    foldSelect.addEventListener('change', function () {
      self.fold = Number(foldSelect.value);
      self.buildFrusta();
      self.render();
    });
    // Picking: a click (not a drag) selects the nearest frustum within 12 px, else the surface.
    var down = null;
    renderer.domElement.addEventListener('pointerdown', function (e) { down = [e.clientX, e.clientY]; });
    renderer.domElement.addEventListener('click', function (e) {
      if (down && Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
      self.pick(e.clientX, e.clientY);
    });
    window.addEventListener('resize', function () { self.resize(); self.render(); });
    this.select(0);
    this.setMode(this.mode);
  }

  View.prototype.resize = function () {
    var w = Math.max(50, this.host.clientWidth), h = Math.max(50, this.host.clientHeight);
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  };

  View.prototype.render = function () {
    this.camera.updateMatrixWorld();
    this.renderer.render(this.scene, this.camera);
  };

  View.prototype.setMode = function (mode) {
    this.mode = mode;
    this.root.querySelectorAll('.v3-modes button').forEach(function (b) {
      b.setAttribute('aria-pressed', b.getAttribute('data-mode') === mode ? 'true' : 'false');
    });
    if (this.material) this.material.uniforms.mode.value = {error: 0, model: 1, unseen: 2}[mode];
    this.updateColourBar();
    this.render();
  };

  // Builds the model's geometry (decoded lazily, once per model).
  // A model's array `name` ("positions", "indices", "colors"), or the earlier model's it
  // refers to ("<name>_of": index).
  View.prototype.array = function (m, name, Type) {
    if (m[name + '_of'] !== undefined) m = this.data.models[m[name + '_of']];
    return m[name] ? decode(m[name], Type) : null;
  };

  View.prototype.select = function (index) {
    var m = this.data.models[index];
    this.modelIndex = index;
    this.root.querySelector('.v3-model').value = String(index);
    if (this.object) { this.scene.remove(this.object); this.object.geometry.dispose(); }
    var pos = this.array(m, 'positions', Float32Array);
    var n = pos.length / 3;
    var err = m.error ? decode(m.error, Float32Array) : new Float32Array(n).fill(NaN);
    var indices = this.array(m, 'indices', Uint32Array);
    var seen = new Float32Array(n), fill = new Float32Array(n), hole = new Float32Array(n);
    var unseen = m.unseen ? decode(m.unseen, Uint8Array) : null;
    for (var i = 0; i < n; ++i) {
      seen[i] = isFinite(err[i]) ? 1 : 0;
      fill[i] = isFinite(err[i]) ? err[i] : 0;
      hole[i] = unseen ? unseen[i] : (isFinite(err[i]) ? 0 : 1);
    }
    if (indices) {
      // An unseen vertex takes the mean error of its seen neighbours (for the interpolation).
      var sum = new Float64Array(n), count = new Uint32Array(n);
      for (var f = 0; f < indices.length; f += 3) {
        for (var k = 0; k < 3; ++k) {
          var a = indices[f + k];
          if (seen[a]) continue;
          for (var l = 1; l < 3; ++l) {
            var b = indices[f + (k + l) % 3];
            if (seen[b]) { sum[a] += err[b]; count[a]++; }
          }
        }
      }
      for (i = 0; i < n; ++i) if (!seen[i] && count[i]) fill[i] = sum[i] / count[i];
    }
    var rgb = new Float32Array(3 * n);
    var c8 = this.array(m, 'colors', Uint8Array);
    if (c8) {
      for (i = 0; i < 3 * n; ++i) rgb[i] = c8[i] / 255;
    } else {
      rgb.fill(0.8);
    }
    var g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    g.setAttribute('err', new THREE.BufferAttribute(fill, 1));
    g.setAttribute('seen', new THREE.BufferAttribute(seen, 1));
    g.setAttribute('rgb', new THREE.BufferAttribute(rgb, 3));
    g.setAttribute('hole', new THREE.BufferAttribute(hole, 1));
    if (indices) g.setIndex(new THREE.BufferAttribute(indices, 1));
    g.computeBoundingBox();
    g.computeBoundingSphere();
    var low = m.low === null ? 0 : m.low, high = m.high === null ? 1 : m.high;
    this.material = new THREE.ShaderMaterial({
      uniforms: {mode: {value: {error: 0, model: 1, unseen: 2}[this.mode]}, low: {value: low},
                 high: {value: high}, isMesh: {value: indices ? 1 : 0}, pointSize: {value: 3}},
      vertexShader: VERTEX, fragmentShader: FRAGMENT, side: THREE.DoubleSide
    });
    this.material.extensions.derivatives = true;
    this.object = indices ? new THREE.Mesh(g, this.material) : new THREE.Points(g, this.material);
    this.scene.add(this.object);
    this.errors = err;
    this.model = m;
    var box = g.boundingBox;
    this.center = box.getCenter(new THREE.Vector3());
    this.extent = box.getSize(new THREE.Vector3()).length() || 1;

    var foldSelect = this.root.querySelector('.v3-fold');
    foldSelect.innerHTML = '';
    var opts = [[-1, 'all folds']].concat(m.folds.map(function (name, k) { return [k, name]; }));
    opts.forEach(function (o) {
      var e = document.createElement('option');
      e.value = String(o[0]);
      e.textContent = o[1];
      foldSelect.appendChild(e);
    });
    this.fold = -1;
    this.selected = null;
    this.buildFrusta();
    this.placeCamera();
    this.updateColourBar();
    var note = this.root.querySelector('.v3-note');
    var text = m.kind === 'mesh'
        ? m.faces + ' triangles' + (m.original_faces > m.faces ? ' (simplified for the browser from ' + m.original_faces + ')' : '')
        : m.vertices + ' points' + (m.original_vertices > m.vertices ? ' (every ' + Math.ceil(m.original_vertices / m.vertices) + 'th of ' + m.original_vertices + ')' : '');
    note.textContent = text + (m.note ? '; ' + m.note : '');
    this.resize();
    this.render();
  };

  // The initial viewpoint: from the photos' side (their mean direction from the model; for a
  // ring of photos the first photo's azimuth) a little above their mean elevation, the whole
  // model and the cameras in view.
  View.prototype.placeCamera = function () {
    var cams = this.allCameras(), self = this;
    var dir = new THREE.Vector3(), up = new THREE.Vector3(), elevation = 0, reach = 0;
    cams.forEach(function (c) {
      var d = c.center.clone().sub(self.center);
      reach = Math.max(reach, d.length());
      dir.add(d.clone().normalize());
      up.add(c.up);
    });
    if (up.length() < 1e-6) up.set(0, 0, 1);
    up.normalize();
    if (cams.length === 0) {
      dir.set(1, -1, 0).normalize();
    } else {
      cams.forEach(function (c) { elevation += c.center.clone().sub(self.center).normalize().dot(up); });
      elevation /= cams.length;
      if (dir.length() < 0.3 * cams.length) dir = cams[0].center.clone().sub(this.center);
      dir.sub(up.clone().multiplyScalar(dir.dot(up)));  // horizontal part
      if (dir.length() < 1e-6) dir.set(1, 0, 0).sub(up.clone().multiplyScalar(up.x));
      dir.normalize();
    }
    var angle = Math.min(1.2, Math.asin(Math.max(-1, Math.min(1, elevation))) + 0.35);
    dir.multiplyScalar(Math.cos(angle)).add(up.clone().multiplyScalar(Math.sin(angle))).normalize();
    var distance = Math.max(this.extent * 1.1, reach * 1.15);
    this.camera.up.copy(up);
    this.camera.near = this.extent * 0.005;
    this.camera.far = (this.extent + reach) * 20;
    this.camera.position.copy(this.center).add(dir.multiplyScalar(distance));
    this.controls.target.copy(this.center);
    this.camera.lookAt(this.center);
    this.camera.updateProjectionMatrix();
    this.controls.update();
  };

  // Cameras of the current model plus the suggested ones, with world geometry.
  View.prototype.allCameras = function () {
    var list = this.model.cameras.concat(this.data.suggested);
    var depth = this.extent * 0.06;
    return list.map(function (c) {
      var R = c.R, t = c.t;
      // world = R^T (x_cam - t)
      function toWorld(x, y, z) {
        var dx = x - t[0], dy = y - t[1], dz = z - t[2];
        return new THREE.Vector3(R[0] * dx + R[3] * dy + R[6] * dz,
                                 R[1] * dx + R[4] * dy + R[7] * dz,
                                 R[2] * dx + R[5] * dy + R[8] * dz);
      }
      var K = c.K, corners = [];
      [[0, 0], [K[4], 0], [K[4], K[5]], [0, K[5]]].forEach(function (p) {
        corners.push(toWorld((p[0] - K[2]) / K[0] * depth, (p[1] - K[3]) / K[1] * depth, depth));
      });
      var center = toWorld(0, 0, 0);
      var up = new THREE.Vector3(-R[3], -R[4], -R[5]);  // -y axis of the camera in world
      return {cam: c, center: center, corners: corners, up: up};
    });
  };

  View.prototype.frustumColour = function (c) {
    if (c.role === 'suggested') return SUGGESTED_COLOUR;
    if (this.fold < 0) return c.test_fold >= 0 ? FOLD_COLOURS[c.test_fold % FOLD_COLOURS.length] : OTHER_COLOUR;
    if (c.test_fold === this.fold) return TEST_COLOUR;
    if (c.train_folds.indexOf(this.fold) >= 0) return TRAIN_COLOUR;
    return null;  // not in this fold
  };

  View.prototype.buildFrusta = function () {
    var group = this.frustumGroup, self = this;
    while (group.children.length) {
      var child = group.children.pop();
      child.geometry.dispose();
    }
    this.frusta = [];
    this.allCameras().forEach(function (f) {
      var colour = self.frustumColour(f.cam);
      if (colour === null) return;
      var p = [], a = f.center, q = f.corners;
      for (var k = 0; k < 4; ++k) {
        p.push(a, q[k], q[k], q[(k + 1) % 4]);
      }
      var g = new THREE.BufferGeometry().setFromPoints(p);
      var line = new THREE.LineSegments(g, new THREE.LineBasicMaterial({color: colour}));
      group.add(line);
      if (f.cam.role === 'suggested' || f.cam === self.selected) {
        // Thick lines are not portable in WebGL: a translucent filled image rectangle instead.
        var rect = new THREE.BufferGeometry().setFromPoints([q[0], q[1], q[2], q[0], q[2], q[3]]);
        group.add(new THREE.Mesh(rect, new THREE.MeshBasicMaterial(
            {color: colour, transparent: true, opacity: f.cam === self.selected ? 0.6 : 0.35,
             side: THREE.DoubleSide})));
      }
      self.frusta.push({name: f.cam.name, role: f.cam.role, cam: f.cam,
                        apex: [a.x, a.y, a.z], corners: q.map(function (v) { return [v.x, v.y, v.z]; })});
    });
    this.updateLegend();
  };

  View.prototype.updateLegend = function () {
    var m = this.model, html = '';
    function item(colour, text) {
      return '<span><i style="background:#' + ('00000' + colour.toString(16)).slice(-6) + '"></i>' + esc(text) + '</span>';
    }
    if (this.fold < 0) {
      m.folds.forEach(function (name, k) {
        html += item(FOLD_COLOURS[k % FOLD_COLOURS.length], 'evaluated in ' + name);
      });
      if (m.cameras.some(function (c) { return c.test_fold < 0; })) html += item(OTHER_COLOUR, 'training only');
    } else {
      html += item(TEST_COLOUR, 'evaluation photos') + item(TRAIN_COLOUR, 'training photos');
    }
    if (this.data.suggested.length) html += item(SUGGESTED_COLOUR, 'suggested next views');
    this.root.querySelector('.v3-legend').innerHTML = html;
  };

  View.prototype.updateColourBar = function () {
    var m = this.model, bar = this.root.querySelector('.v3-colorbar');
    if (this.mode === 'error' && m.low !== null && m.high !== null) {
      var stops = [0, 0.125, 0.375, 0.625, 0.875, 1].map(function (t) {
        var c = jet(t);
        return 'rgb(' + c.map(function (v) { return Math.round(255 * v); }).join(',') + ') ' + (100 * t) + '%';
      });
      bar.innerHTML = '<span>' + esc(m.metric) + ' error</span><span>' + fmt(m.low) +
          '</span><span class="bar" style="background:linear-gradient(to right,' + stops.join(',') +
          ')"></span><span>' + fmt(m.high) + '</span><span class="muted">grey = seen by no ' +
          'evaluation view; range = the projection\u2019s (2.5\u201397.5 % of the vertex errors)</span>';
    } else if (this.mode === 'unseen') {
      bar.innerHTML = '<span><i style="display:inline-block;width:12px;height:12px;background:#e0119e"></i> ' +
          'seen by no photo</span>';
    } else {
      bar.innerHTML = (m.colors || m.colors_of !== undefined) ? '<span>the model\u2019s own colours</span>' :
          '<span class="muted">no model colours in this report (see the note below)</span>';
    }
  };

  // Column-major projection * view matrix (for tests and overlays).
  View.prototype.viewProjection = function () {
    this.camera.updateMatrixWorld();
    var m = new THREE.Matrix4().multiplyMatrices(this.camera.projectionMatrix, this.camera.matrixWorldInverse);
    return Array.prototype.slice.call(m.elements);
  };

  View.prototype.toScreen = function (p) {
    var v = new THREE.Vector3(p[0], p[1], p[2]).project(this.camera);
    var r = this.renderer.domElement.getBoundingClientRect();
    return {x: r.left + (v.x + 1) / 2 * r.width, y: r.top + (1 - v.y) / 2 * r.height, z: v.z};
  };

  View.prototype.pick = function (x, y) {
    var best = null, bestDistance = 12, self = this;
    this.frusta.forEach(function (f) {
      [f.apex].concat(f.corners).forEach(function (p) {
        var s = self.toScreen(p);
        if (s.z < -1 || s.z > 1) return;
        var d = Math.hypot(s.x - x, s.y - y);
        if (d < bestDistance) { bestDistance = d; best = f; }
      });
    });
    if (best) { this.showCamera(best.cam); return; }
    var r = this.renderer.domElement.getBoundingClientRect();
    var ndc = new THREE.Vector2((x - r.left) / r.width * 2 - 1, -((y - r.top) / r.height) * 2 + 1);
    var ray = new THREE.Raycaster();
    ray.params.Points.threshold = this.extent * 0.004;
    ray.setFromCamera(ndc, this.camera);
    var hits = ray.intersectObject(this.object);
    if (hits.length) this.showPoint(hits[0]);
  };

  View.prototype.showCamera = function (c) {
    var info = this.root.querySelector('.v3-info');
    this.selected = c;  // drawn with a filled image rectangle
    this.buildFrusta();
    this.render();
    var role;
    if (c.role === 'suggested') role = 'suggested next view';
    else if (this.fold >= 0) role = c.test_fold === this.fold ? 'evaluation photo of ' + this.model.folds[this.fold] : 'training photo of ' + this.model.folds[this.fold];
    else role = c.test_fold >= 0 ? 'evaluated in ' + this.model.folds[c.test_fold] : 'training photo';
    var html = '<h4 class="v3-selected" data-name="' + esc(c.name) + '">' + esc(c.name) + '</h4><p>' +
        esc(role) + (c.error !== null ? '<br>' + esc(this.model.metric) + (c.role === 'suggested' ? ' (mean projected error it looks at) ' : ' ') + fmt(c.error) : '') +
        (c.note ? '<br>' + esc(c.note) : '') + '</p>';
    var images = this.data.images || [];
    [['photo', 'photo'], ['rephoto', 'rephoto'], ['error_image', this.model.metric + ' error']].forEach(function (p) {
      var uri = typeof c[p[0]] === 'number' ? images[c[p[0]]] : null;
      if (uri && /^data:image\/(jpeg|png);base64,/.test(uri)) {
        html += '<div>' + esc(p[1]) + '<img src="' + uri + '" alt="' + esc(p[1]) + '"></div>';
      }
    });
    info.innerHTML = html;
  };

  View.prototype.showPoint = function (hit) {
    var p = hit.point, m = this.model, err = NaN;
    if (hit.face) {
      // Barycentric interpolation of the corner errors, as the shader does.
      var a = hit.face.a, b = hit.face.b, c = hit.face.c, e = this.errors;
      var pos = this.object.geometry.attributes.position;
      var A = new THREE.Vector3().fromBufferAttribute(pos, a), B = new THREE.Vector3().fromBufferAttribute(pos, b),
          C = new THREE.Vector3().fromBufferAttribute(pos, c);
      var bary = THREE.Triangle.getBarycoord(p, A, B, C, new THREE.Vector3());
      var s = 0, w = 0;
      [[a, bary.x], [b, bary.y], [c, bary.z]].forEach(function (q) {
        if (isFinite(e[q[0]])) { s += e[q[0]] * q[1]; w += q[1]; }
      });
      if (w > 0) err = s / w;
    } else if (hit.index !== undefined) {
      err = this.errors[hit.index];
    }
    // The views that see p: in front, inside the image, not hidden by the model.
    var rows = [], ray = new THREE.Raycaster(), self = this;
    this.allCameras().forEach(function (f) {
      var c = f.cam, R = c.R, t = c.t, K = c.K;
      var x = R[0] * p.x + R[1] * p.y + R[2] * p.z + t[0];
      var y = R[3] * p.x + R[4] * p.y + R[5] * p.z + t[1];
      var z = R[6] * p.x + R[7] * p.y + R[8] * p.z + t[2];
      if (!(z > 0)) return;
      var u = K[0] * x / z + K[2], v = K[1] * y / z + K[3];
      if (u < 0 || v < 0 || u >= K[4] || v >= K[5]) return;
      var d = p.clone().sub(f.center), distance = d.length();
      ray.set(f.center, d.normalize());
      ray.far = distance * (1 + 1e-3) + self.extent * 1e-4;
      ray.params.Points.threshold = self.extent * 0.002;
      var h = ray.intersectObject(self.object);
      if (h.length && h[0].distance < distance - self.extent * 2e-3) return;
      rows.push(c);
    });
    var html = '<h4>surface point</h4><p>(' + [p.x, p.y, p.z].map(fmt).join(', ') + ')<br>' +
        esc(m.metric) + ' error here ' + fmt(err) + '</p><p>' + rows.length + ' view' +
        (rows.length === 1 ? '' : 's') + ' see it:</p><table><thead><tr><th class="text">view</th><th class="text">role</th><th>' +
        esc(m.metric) + ' (image)</th></tr></thead><tbody>';
    rows.forEach(function (c) {
      var role = c.role === 'suggested' ? 'suggested' : (c.test_fold >= 0 ? 'evaluated (' + m.folds[c.test_fold] + ')' : 'training');
      html += '<tr><td class="text">' + esc(c.name) + '</td><td class="text">' + esc(role) + '</td><td>' + fmt(c.error) + '</td></tr>';
    });
    this.root.querySelector('.v3-info').innerHTML = html + '</tbody></table>';
  };

  function start() {
    document.querySelectorAll('.view3d').forEach(function (root) {
      if (root.getAttribute('data-ready')) return;
      try {
        if (typeof THREE === 'undefined') throw new Error('three.js did not load');
        var data = JSON.parse(root.querySelector('.v3-data').textContent);
        var view = new View(root, data);
        registry.views[root.id] = {
          view: view, three: THREE, camera: view.camera, canvas: view.renderer.domElement,
          render: function () { view.render(); },
          viewProjection: function () { return view.viewProjection(); },
          get frusta() { return view.frusta; },
          select: function (i) { view.select(i); },
          setMode: function (m) { view.setMode(m); },
          info: root.querySelector('.v3-info')
        };
        root.setAttribute('data-ready', '1');
      } catch (e) {
        root.setAttribute('data-error', String(e && e.message || e));
        var note = root.querySelector('.v3-note');
        if (note) note.textContent = 'The 3D view could not start (' + (e && e.message || e) + '); it needs WebGL.';
      }
    });
  }
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start);
  else start();
})();
