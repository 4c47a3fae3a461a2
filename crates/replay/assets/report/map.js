// The interactive map of vgps's report.html (drawn with the inlined Leaflet 1.9.4).
// Data: the global VGPS (written by vgps_replay::report::report_html). Frame rows:
// [frame, time_s, status index, fix or null, satellite [lat, lon] or null,
//  truth [lat, lon] or null, indices of the landmarks used]; a fix is
// [lat, lon, sigma_e, sigma_n, sigma_u, cov_ee, cov_en, cov_nn, n_surveyed, n_surrogates,
//  heading_deg].
(function () {
  'use strict';
  var D = window.VGPS;
  var CHI2_95 = 5.991464547107979; // chi-square, 2 degrees of freedom, 95 %
  var A = 6378137.0, E2 = 6.69437999014e-3; // WGS84
  var COLOURS = { truth: '#1ea03c', gnss: '#286edc', visual: '#dc2828', landmark: '#222' };
  var SIGMA_BINS = [[0.02, '#1a9850'], [0.05, '#91cf60'], [0.10, '#fee08b'], [0.25, '#fc8d59'], [Infinity, '#d73027']];
  var panel = document.getElementById('vgps-frame');
  var frames = D.frames;

  function el(id) { return document.getElementById(id); }
  function fmt(x, d) { return (x === null || x === undefined || !isFinite(x)) ? '\u2013' : x.toFixed(d); }
  function iso(t) { return isFinite(t) ? new Date(t * 1000).toISOString() : '\u2013'; }
  // Metres east and north of b to a (local tangent at b: exact to far below a millimetre
  // over the few metres compared here, and to about 0.1 % at a few kilometres).
  function enuOf(a, b) {
    var lat = b[0] * Math.PI / 180, s = Math.sin(lat), w = Math.sqrt(1 - E2 * s * s);
    var m = A * (1 - E2) / (w * w * w), n = A / w;
    return [(a[1] - b[1]) * Math.PI / 180 * n * Math.cos(lat), (a[0] - b[0]) * Math.PI / 180 * m];
  }
  function latLngAt(p, de, dn) {
    var lat = p[0] * Math.PI / 180, s = Math.sin(lat), w = Math.sqrt(1 - E2 * s * s);
    var m = A * (1 - E2) / (w * w * w), n = A / w;
    return [p[0] + dn / m * 180 / Math.PI, p[1] + de / (n * Math.cos(lat)) * 180 / Math.PI];
  }
  function sigmaH(f) { return Math.sqrt(Math.max(f[2] * f[2], f[3] * f[3])); }
  function sigmaColour(s) {
    for (var i = 0; i < SIGMA_BINS.length; i++) { if (s < SIGMA_BINS[i][0]) { return SIGMA_BINS[i][1]; } }
    return SIGMA_BINS[SIGMA_BINS.length - 1][1];
  }
  function statusColour(row) {
    var f = row[3];
    if (!f) { return '#888'; }
    return f[8] >= 3 ? '#2060c0' : '#f08c00';
  }
  // The 95 % ellipse of [cov_ee, cov_en, cov_nn] around a fix, as latitude-longitude points.
  function ellipse(f) {
    var a = f[5], b = f[6], c = f[7];
    var mean = 0.5 * (a + c), d = Math.sqrt(0.25 * (a - c) * (a - c) + b * b);
    var l1 = Math.max(mean + d, 0), l2 = Math.max(mean - d, 0);
    var th = 0.5 * Math.atan2(2 * b, a - c);
    var r1 = Math.sqrt(CHI2_95 * l1), r2 = Math.sqrt(CHI2_95 * l2), pts = [];
    for (var k = 0; k < 32; k++) {
      var u = 2 * Math.PI * k / 32, x = r1 * Math.cos(u), y = r2 * Math.sin(u);
      pts.push(latLngAt(f, x * Math.cos(th) - y * Math.sin(th), x * Math.sin(th) + y * Math.cos(th)));
    }
    return { pts: pts, a: r1, b: r2 };
  }

  var map = L.map('vgps-map', { preferCanvas: true, maxZoom: 30, zoomSnap: 0.25, zoomDelta: 0.5, attributionControl: true });
  var renderer = L.canvas({ padding: 0.3, tolerance: 5 });
  L.control.scale({ imperial: false, maxWidth: 160 }).addTo(map);
  var layers = {}, bounds = L.latLngBounds([]);
  function group(name) { layers[name] = L.layerGroup(); return layers[name]; }
  function track(name, pick, colour, weight) {
    var g = group(name), run = [];
    function flush() {
      if (run.length > 1) { L.polyline(run, { renderer: renderer, color: colour, weight: weight, opacity: 0.8, interactive: false }).addTo(g); }
      run = [];
    }
    frames.forEach(function (r) {
      var p = pick(r);
      if (p) { run.push([p[0], p[1]]); bounds.extend([p[0], p[1]]); } else { flush(); }
    });
    flush();
    return g;
  }
  if (D.has_truth) { track('truth', function (r) { return r[5]; }, COLOURS.truth, 3); }
  track('gnss', function (r) { return r[4]; }, COLOURS.gnss, 1.5);
  track('visual', function (r) { return r[3]; }, COLOURS.visual, 1);

  // Landmarks: small rimmed circles, yellow when used by at least one fix.
  var lm = group('landmarks');
  D.landmarks.forEach(function (l, i) {
    L.circleMarker([l[1], l[2]], { renderer: renderer, radius: 3, color: l[3] > 0 ? '#000' : '#999', weight: 1, fillColor: l[3] > 0 ? '#ffd000' : '#fff', fillOpacity: 1 })
      .bindTooltip('landmark ' + l[0] + ' (used by ' + l[3] + ' fixes)').addTo(lm);
  });

  // One marker per frame: the fix, or (no fix) where the satellite or the truth puts it.
  var colourBy = 'sigma', markers = [];
  var pts = group('frames');
  frames.forEach(function (r, k) {
    var f = r[3], p = f || r[4] || r[5];
    if (!p) { return; }
    bounds.extend([p[0], p[1]]);
    var m = L.circleMarker([p[0], p[1]], { renderer: renderer, radius: f ? 3.5 : 2.5, weight: f ? 1 : 0, color: '#333', fillOpacity: f ? 0.95 : 0.6 });
    m.on('click', function () { show(k); });
    m.addTo(pts);
    markers.push([m, r]);
  });
  function recolour() {
    markers.forEach(function (mr) {
      var r = mr[1], f = r[3];
      var c = colourBy === 'status' ? statusColour(r) : (f ? sigmaColour(sigmaH(f)) : '#888');
      mr[0].setStyle({ fillColor: c });
    });
    el('vgps-key-sigma').style.display = colourBy === 'sigma' ? '' : 'none';
    el('vgps-key-status').style.display = colourBy === 'status' ? '' : 'none';
  }

  // 95 % ellipses: built when first zoomed in far enough to see them.
  var ellipses = null, ELLIPSE_ZOOM = 18;
  function updateEllipses() {
    var want = el('vgps-show-ellipses').checked && map.getZoom() >= ELLIPSE_ZOOM;
    if (want && !ellipses) {
      ellipses = L.layerGroup();
      frames.forEach(function (r) {
        if (r[3]) { L.polygon(ellipse(r[3]).pts, { renderer: renderer, color: '#7030a0', weight: 1, fillOpacity: 0.08, interactive: false }).addTo(ellipses); }
      });
    }
    if (ellipses) {
      if (want && !map.hasLayer(ellipses)) { ellipses.addTo(map); }
      if (!want && map.hasLayer(ellipses)) { map.removeLayer(ellipses); }
    }
  }

  // The selected frame: its fix, its ellipse, lines to the landmarks it used.
  var selection = L.layerGroup().addTo(map);
  function show(k) {
    var r = frames[k], f = r[3], p = f || r[4] || r[5];
    selection.clearLayers();
    var h = '<b>Frame ' + r[0] + '</b> <span class="t">' + iso(r[1]) + '</span><br/>status <b>' + D.statuses[r[2]] + '</b>';
    if (f) {
      var e = ellipse(f);
      h += '<br/>inliers ' + (f[8] + f[9]) + ': ' + f[8] + ' surveyed + ' + f[9] + ' surrogates' +
        '<br/>visual ' + f[0].toFixed(8) + '\u00b0, ' + f[1].toFixed(8) + '\u00b0' +
        '<br/>\u03c3 east / north / up ' + fmt(f[2], 3) + ' / ' + fmt(f[3], 3) + ' / ' + fmt(f[4], 3) + ' m' +
        '<br/>95 % ellipse ' + fmt(e.a, 3) + ' \u00d7 ' + fmt(e.b, 3) + ' m; heading ' + fmt(f[10], 2) + '\u00b0';
      L.polygon(e.pts, { renderer: renderer, color: '#7030a0', weight: 2, fillOpacity: 0.15, interactive: false }).addTo(selection);
      var used = r[6].map(function (i) { return D.landmarks[i]; });
      h += '<br/>landmarks used: ' + (used.length ? used.map(function (l) { return l[0]; }).join(', ') : (f[8] ? f[8] + ' (ids not recorded)' : 'none surveyed'));
      used.forEach(function (l) {
        L.polyline([[f[0], f[1]], [l[1], l[2]]], { renderer: renderer, color: '#000', weight: 1, dashArray: '4 3', interactive: false }).addTo(selection);
      });
    } else {
      h += '<br/>no visual fix';
    }
    if (r[4]) {
      h += '<br/>satellite GPS ' + r[4][0].toFixed(8) + '\u00b0, ' + r[4][1].toFixed(8) + '\u00b0';
      if (f) { var d = enuOf(f, r[4]); h += '<br/>visual \u2212 satellite: ' + fmt(d[0], 3) + ' m east, ' + fmt(d[1], 3) + ' m north'; }
      L.circleMarker([r[4][0], r[4][1]], { renderer: renderer, radius: 5, color: COLOURS.gnss, weight: 2, fill: false, interactive: false }).addTo(selection);
    } else {
      h += '<br/>satellite GPS: none (blackout or gap)';
    }
    if (D.has_truth && r[5]) {
      if (f) { var t = enuOf(f, r[5]); h += '<br/>visual \u2212 truth: ' + fmt(t[0], 3) + ' m east, ' + fmt(t[1], 3) + ' m north'; }
      L.circleMarker([r[5][0], r[5][1]], { renderer: renderer, radius: 5, color: COLOURS.truth, weight: 2, fill: false, interactive: false }).addTo(selection);
    }
    if (p) { L.circleMarker([p[0], p[1]], { renderer: renderer, radius: 7, color: '#000', weight: 2, fill: false, interactive: false }).addTo(selection); }
    panel.innerHTML = h;
    panel.setAttribute('data-frame', String(r[0]));
  }

  // Optional online background (asked for only when ticked: the page works offline).
  var background = null;
  function updateBackground() {
    var want = el('vgps-show-background').checked;
    if (want && !background) {
      background = L.tileLayer('https://tile.openstreetmap.org/{z}/{x}/{y}.png', { maxNativeZoom: 19, maxZoom: 30, attribution: '\u00a9 OpenStreetMap contributors' });
    }
    if (background) {
      if (want && !map.hasLayer(background)) { background.addTo(map); background.bringToBack(); }
      if (!want && map.hasLayer(background)) { map.removeLayer(background); }
    }
  }

  function toggle(id, name) {
    var box = el(id);
    if (!box) { return; }
    function apply() { if (box.checked) { layers[name].addTo(map); } else { map.removeLayer(layers[name]); } }
    box.addEventListener('change', apply);
    apply();
  }
  toggle('vgps-show-truth', 'truth');
  toggle('vgps-show-gnss', 'gnss');
  toggle('vgps-show-visual', 'visual');
  toggle('vgps-show-landmarks', 'landmarks');
  layers.frames.addTo(map);
  el('vgps-show-ellipses').addEventListener('change', updateEllipses);
  el('vgps-show-background').addEventListener('change', updateBackground);
  el('vgps-colour').addEventListener('change', function (ev) { colourBy = ev.target.value; recolour(); });
  map.on('zoomend', updateEllipses);
  recolour();
  if (bounds.isValid()) { map.fitBounds(bounds.pad(0.05)); } else { map.setView([D.origin[0], D.origin[1]], 18); }
  updateEllipses();
  // Milliseconds from the start of the page's loading to the map built (Leaflet draws it
  // at the next animation frame).
  var readyMs = performance.now();

  // Self-test (report.html#selftest, used by vgps's headless-browser test): zoom to the
  // first fix, click where it is drawn, and write what happened into #vgps-selftest.
  function canvasInk() {
    var c = map.getPanes().overlayPane.querySelector('canvas');
    if (!c || !c.width) { return 0; }
    var px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data, n = 0;
    for (var i = 3; i < px.length; i += 4) { if (px[i]) { n++; } }
    return n;
  }
  if (window.location.hash === '#selftest') {
    var out = { errors: window.VGPS_ERRORS, frames: frames.length, ready_ms: Math.round(readyMs) };
    setTimeout(function () {
      out.ink_whole_drive = canvasInk();
      out.drawn_ms = Math.round(performance.now());
      var k = -1;
      for (var i = 0; i < frames.length; i++) { if (frames[i][3]) { k = i; break; } }
      if (k < 0) { finish(); return; }
      var f = frames[k][3];
      map.setView([f[0], f[1]], 26, { animate: false });
      setTimeout(function () {
        var c = map.getPanes().overlayPane.querySelector('canvas');
        var pt = map.latLngToContainerPoint([f[0], f[1]]), box = map.getContainer().getBoundingClientRect();
        out.zoom = map.getZoom();
        out.metres_per_pixel = 40075016.686 * Math.cos(f[0] * Math.PI / 180) / Math.pow(2, map.getZoom() + 8);
        out.ellipses_drawn = ellipses !== null && map.hasLayer(ellipses);
        var init = { bubbles: true, cancelable: true, clientX: box.left + pt.x, clientY: box.top + pt.y, view: window };
        c.dispatchEvent(new MouseEvent('mousedown', init));
        c.dispatchEvent(new MouseEvent('mouseup', init));
        c.dispatchEvent(new MouseEvent('click', init));
        out.clicked_frame = frames[k][0];
        out.panel_frame = panel.getAttribute('data-frame');
        out.panel = panel.textContent;
        finish();
      }, 300);
    }, 200);
    function finish() {
      out.resources = performance.getEntriesByType('resource').map(function (r) { return r.name; });
      out.errors = window.VGPS_ERRORS;
      el('vgps-selftest').textContent = JSON.stringify(out);
    }
  }
}());
