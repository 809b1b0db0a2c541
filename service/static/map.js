// The live map of csws (GET /map): the roads of one served network, its curves in the view coloured
// by minimum radius, and the live vehicles, asked for once a second; where the network has a map report
// (GET /v1/report), a layer of what its map shows wrong or doubtful, off until ticked. No tiles: it works offline.
// Address: /map?network=NAME#key=API_KEY&map=ZOOM/Y/X&vehicle=ID (all optional): the view (centre as
// lat/lon, or network y/x in metres) and the selected vehicle are kept in the fragment, so a view can be shared.
"use strict";

const NETWORKS = JSON.parse(document.getElementById("networks").textContent);
const FRAGMENT = new URLSearchParams(location.hash.slice(1));
const KEY = FRAGMENT.get("key");
const HEADERS = KEY ? { Authorization: "Bearer " + KEY } : {};
const FLEET_PERIOD_MS = 1000;
// Vehicles per request of /v1/fleet: the service's largest page (service.fleet.MAX_PAGE_SIZE).
const FLEET_PAGE_SIZE = 10000;
// How many of the latest fleet refreshes the page keeps the timing of (for benchmarks/map.py).
const REFRESHES_KEPT = 120;

// Curves: upper bound of minimum radius (m) and colour, sharpest first; R_c = 300 m (3.2).
const RADIUS_CLASSES = [[40, "#800026"], [80, "#bd0026"], [120, "#e31a1c"], [200, "#fc4e2a"], [300, "#fd8d3c"]];
// Curves at city scale (coarser than this, m per pixel: zoom below about 15.6 at 50° N) are drawn thin and
// light, so the vehicles stay visible among them; closer in, full.
const CITY_METRES_PER_PIXEL = 2;
const CURVE_STYLES = { city: { weight: 2, opacity: 0.45 }, street: { weight: 5, opacity: 0.9 } };
// Vehicles: system state (5.2-5.4), and the warning level when active (6.1). The fills are from Okabe and
// Ito's palette for colour-blind readers and share none with the curves' reds and oranges; the level is
// told by size and outline too (no warning a small dot, level 1 a larger pink disc ringed in black, level 2
// the largest, indigo with a thick pink ring), a fault by its dashed outline.
const VEHICLE_STYLES = {
  off: { fillColor: "#bbbbbb", color: "#666666", radius: 4, weight: 1, dashArray: null },
  standby: { fillColor: "#ffffff", color: "#0072b2", radius: 4, weight: 2, dashArray: null },
  fault: { fillColor: "#f0e442", color: "#000000", radius: 6, weight: 2, dashArray: "2 2" },
  "active-0": { fillColor: "#0072b2", color: "#ffffff", radius: 4, weight: 1, dashArray: null },
  "active-1": { fillColor: "#cc79a7", color: "#000000", radius: 7, weight: 2, dashArray: null },
  "active-2": { fillColor: "#332288", color: "#cc79a7", radius: 10, weight: 4, dashArray: null },
};
// Silence since a vehicle's last fix (the service's time of its latest answer), s: faded after FADE_AFTER_S,
// no longer drawn after GONE_AFTER_S (its session lives on in the store until it expires).
const FADE_AFTER_S = 30;
const GONE_AFTER_S = 120;
const FADED_OPACITY = 0.3;
// The map report: colour of each kind of item (csws.osm.report.KINDS).
const REPORT_COLOURS = {
  "artefact-spike": "#6a3d9a", "artefact-fold": "#6a3d9a", "artefact-jog": "#6a3d9a", "artefact-zigzag": "#6a3d9a",
  "floor-curve": "#b15928", "single-node-corner": "#1f78b4", "border-cut": "#000000", dropped: "#737373",
};
const VEHICLE_LABELS = {
  off: "off", standby: "standby", fault: "fault",
  "active-0": "active, no warning", "active-1": "level 1 warning", "active-2": "level 2 warning",
};
const COMPASS = ["N", "NE", "E", "SE", "S", "SW", "W", "NW"];

const chosen = new URLSearchParams(location.search).get("network")
  || (NETWORKS.find((n) => n.geo_referenced) || NETWORKS[0]).name;
const network = NETWORKS.find((n) => n.name === chosen) || NETWORKS[0];
// One canvas for roads, curves, the report and vehicles, so a click finds whichever is on top (a canvas in a
// pane above would take every click); the vehicles are kept last in its drawing order (keepVehiclesOnTop).
const renderer = L.canvas({ padding: 0.3 });
const map = L.map("map", {
  crs: network.geo_referenced ? L.CRS.EPSG3857 : L.CRS.Simple,
  preferCanvas: true, renderer: renderer, zoomSnap: 0.25,
  minZoom: network.geo_referenced ? 2 : -10, maxZoom: network.geo_referenced ? 22 : 6,
});
map.attributionControl.setPrefix('<a href="/static/leaflet/LICENSE">Leaflet</a>');
if (network.geo_referenced) map.attributionControl.addAttribution("map data © OpenStreetMap contributors");

const roads = L.layerGroup().addTo(map);
const curves = L.layerGroup().addTo(map);
const report = L.layerGroup();  // the map report, shown when ticked in the layers control
const vehicles = new Map();  // vehicle id -> circleMarker, updated in place
const status = panel("bottomleft", "");
const dataset = document.body.dataset;
let selected = FRAGMENT.get("vehicle");  // the vehicle whose popup is open (or is to open when it shows up)
let fleetClock = { generated_s: null, received_ms: 0 };  // the service's time of the latest fleet answer

function panel(position, html) {
  const control = L.control({ position: position });
  control.onAdd = () => { const div = L.DomUtil.create("div", "panel"); div.innerHTML = html; return div; };
  control.addTo(map);
  L.DomEvent.disableClickPropagation(control.getContainer());
  L.DomEvent.disableScrollPropagation(control.getContainer());
  return control.getContainer();
}

function escaped(text) {
  return String(text ?? "").replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);
}

async function get(path) {
  const response = await fetch(path, { headers: HEADERS });
  if (!response.ok) {
    const hint = response.status === 401 ? " (open the map as /map#key=YOUR_API_KEY)" : "";
    throw new Error(`${path.split("?")[0]}: HTTP ${response.status}${hint}`);
  }
  return response.json();
}

function viewBbox() {
  const b = map.getBounds();
  return [b.getWest(), b.getSouth(), b.getEast(), b.getNorth()].map((v) => v.toFixed(7)).join(",");
}

// ---------------------------------------------------------------- the view and the selection in the address

function writeAddress() {
  const c = map.getCenter();
  const digits = network.geo_referenced ? 6 : 1;
  const fragment = new URLSearchParams();
  if (KEY) fragment.set("key", KEY);
  fragment.set("map", `${map.getZoom()}/${c.lat.toFixed(digits)}/${c.lng.toFixed(digits)}`);
  if (selected) fragment.set("vehicle", selected);
  history.replaceState(null, "", "#" + fragment.toString().replace(/%2F/g, "/"));
}

function addressedView() {
  const parts = (FRAGMENT.get("map") || "").split("/").map(Number);
  return parts.length === 3 && parts.every(Number.isFinite) ? { zoom: parts[0], centre: [parts[1], parts[2]] } : null;
}

// ---------------------------------------------------------------- curves and the map report

function radiusColour(radius_m) {
  const found = RADIUS_CLASSES.find(([upTo]) => radius_m <= upTo);
  return (found || RADIUS_CLASSES[RADIUS_CLASSES.length - 1])[1];
}

function metresPerPixel() {
  const middle = map.getSize().divideBy(2);
  const a = map.containerPointToLatLng(middle), b = map.containerPointToLatLng(middle.add([100, 0]));
  return map.distance(a, b) / 100;
}

function curveStyle(radius_m) {
  const scale = metresPerPixel() > CITY_METRES_PER_PIXEL ? CURVE_STYLES.city : CURVE_STYLES.street;
  return { color: radiusColour(radius_m), ...scale };
}

function curvePopup(p) {
  const rows = Object.entries(p.warning_speed_kmh).map(([category, levels]) =>
    `<tr><th>${category}</th><td>${levels["1"].toFixed(1)}</td><td>${levels["2"].toFixed(1)}</td></tr>`).join("");
  return `<b>${escaped(p.street_name) || "(unnamed road)"}</b> ${escaped(p.road_type)}<br>`
    + `minimum radius ${p.radius_m.toFixed(1)} m, angle ${p.angle_deg.toFixed(1)}°, ${p.direction}<br>`
    + `${p.parts.length} part(s); ${escaped(p.curve_id)}`
    + `<table class="vw"><tr><th>V_w km/h</th><th>level 1</th><th>level 2</th></tr>${rows}</table>`;
}

function reportPopup(p) {
  const corner = p.real_corner === undefined ? "" : (p.real_corner ? " (real corner)" : " (artefact)");
  const way = p.way_id === null ? "no OSM way" : `OSM way ${p.way_id}`;
  return `<b>${escaped(p.kind)}</b>${corner}, ${p.size.toFixed(2)} ${escaped(p.unit)}<br>${way}`
    + `${p.edge_id ? ", edge " + escaped(p.edge_id) : ""}<br>${escaped(p.reason)}`;
}

async function loadReport() {
  if (!network.report) return;
  const data = await get(`/v1/report?network=${encodeURIComponent(network.name)}`);
  L.geoJSON(data, {
    renderer: renderer,
    pointToLayer: (f, latlng) => L.circleMarker(latlng, {
      renderer: renderer, radius: 6, weight: 2, color: REPORT_COLOURS[f.properties.kind], fillOpacity: 0.3,
    }),
    style: (f) => ({
      color: REPORT_COLOURS[f.properties.kind], weight: 4, opacity: 0.8,
      dashArray: f.geometry.type === "LineString" && f.properties.kind !== "floor-curve" ? "6 6" : null,
    }),
    onEachFeature: (f, layer) => { layer.bindPopup(() => reportPopup(f.properties)); report.addLayer(layer); },
  });
  const label = `map report: ${data.features.length} item(s)`;
  L.control.layers(null, { [label]: report }, { position: "topleft", collapsed: false }).addTo(map);
  map.on("overlayadd", keepVehiclesOnTop);
  dataset.reportFeatures = String(data.features.length);
}

function restyleCurves() {
  curves.eachLayer((layer) => layer.setStyle(curveStyle(layer.feature.properties.radius_m)));
}

let curveRequest = 0;
async function loadCurves() {
  const request = ++curveRequest;
  const bbox = viewBbox();
  const data = await get(`/v1/curves?network=${encodeURIComponent(network.name)}&bbox=${bbox}`);
  if (request !== curveRequest) return;  // the view moved on meanwhile
  curves.clearLayers();
  L.geoJSON(data, {
    renderer: renderer,
    style: (f) => curveStyle(f.properties.radius_m),
    onEachFeature: (f, layer) => { layer.bindPopup(() => curvePopup(f.properties)); curves.addLayer(layer); },
  });
  keepVehiclesOnTop();
  dataset.curvesBbox = bbox;
  dataset.curvesDrawn = String(curves.getLayers().length);
  showStatus();
}

// ---------------------------------------------------------------- vehicles

function vehicleKind(p) {
  return p.state === "active" ? `active-${p.level}` : p.state;
}

function keepVehiclesOnTop() {
  for (const marker of vehicles.values()) marker.bringToFront();
}

// Seconds since the service answered the vehicle's latest fix, on the service's clock; null if unknown.
function silenceS(p) {
  if (p.answered_at_s == null || fleetClock.generated_s == null) return null;
  return fleetClock.generated_s - p.answered_at_s + (performance.now() - fleetClock.received_ms) / 1000;
}

function vehicleStyle(p) {
  const faded = (silenceS(p) ?? 0) > FADE_AFTER_S;
  return { ...VEHICLE_STYLES[vehicleKind(p)], opacity: faded ? FADED_OPACITY : 1, fillOpacity: faded ? FADED_OPACITY : 1 };
}

function heading(deg) {
  return deg == null ? "not sent" : `${Math.round(deg)}° (${COMPASS[((Math.round(deg / 45) % 8) + 8) % 8]})`;
}

function vehiclePopup(p) {
  const silence = silenceS(p);
  const target = p.curve_id == null ? "none"
    : `${escaped(p.curve_id)}, V_w ${p.warning_speed_kmh.toFixed(1)} km/h`;
  const rows = [
    ["street", `${escaped(p.street_name) || "(unnamed road)"} ${escaped(p.road_type)}`],
    ["target curve", target],
    ["speed", `${p.speed_kmh.toFixed(1)} km/h`],
    ["heading", heading(p.heading_deg)],
    ["category", escaped(p.category ?? "unknown")],
    ["last fix", silence == null ? "unknown" : `${Math.max(0, silence).toFixed(0)} s ago`],
    ["lane", escaped(p.lane_id)],
  ].map(([name, value]) => `<tr><th>${name}</th><td data-field="${name}">${value}</td></tr>`).join("");
  return `<b>${escaped(p.vehicle_id)}</b>: ${VEHICLE_LABELS[vehicleKind(p)]}${p.fault ? ": " + escaped(p.fault) : ""}`
    + `<table class="vehicle">${rows}</table>`;
}

function select(id) {
  const marker = vehicles.get(id);
  if (marker === undefined) return;
  if (!map.getBounds().contains(marker.getLatLng())) map.panTo(marker.getLatLng());
  marker.openPopup();
}

function placeVehicle(f) {
  const p = f.properties;
  const [x, y] = f.geometry.coordinates;
  const style = vehicleStyle(p);
  let marker = vehicles.get(f.id);
  if (marker === undefined) {
    marker = L.circleMarker([y, x], { renderer: renderer, ...style });
    marker.bindPopup(() => vehiclePopup(marker.properties));
    marker.on("popupopen", () => { selected = f.id; writeAddress(); });
    marker.on("popupclose", () => { if (selected === f.id) { selected = null; writeAddress(); } });
    vehicles.set(f.id, marker.addTo(map));
  } else {
    marker.setLatLng([y, x]);
    if (Object.entries(style).some(([name, value]) => marker.options[name] !== value)) marker.setStyle(style);
  }
  marker.properties = p;
  if (marker.isPopupOpen()) marker.setPopupContent(vehiclePopup(p));
}

let warnedHtml = "";
// The vehicles warned now (level 1 or 2, drawn), most urgent first, each a button that selects it.
function listWarned() {
  const warned = [...vehicles.values()].map((m) => m.properties)
    .filter((p) => p.state === "active" && p.level >= 1)
    .sort((a, b) => b.level - a.level || a.vehicle_id.localeCompare(b.vehicle_id));
  const shapes = warned.map((p) => `<li><button data-vehicle="${escaped(p.vehicle_id)}">`
    + `${shapeSvg(VEHICLE_STYLES[vehicleKind(p)])}${escaped(p.vehicle_id)} · level ${p.level}`
    + `${p.curve_id == null ? "" : " · V_w " + p.warning_speed_kmh.toFixed(0) + " km/h"}</button></li>`);
  warnedPanel.querySelector("h4").textContent = `warned now: ${warned.length}`;
  const html = shapes.join("");
  if (html !== warnedHtml) warnedPanel.querySelector("#warned").innerHTML = warnedHtml = html;
}

// ---------------------------------------------------------------- recent warnings (GET /v1/events)
// The fleet's latest warning events on this network, newest first, as the service's event stream sends them:
// streams of a second each (the list is at most that late), read whole with fetch, which sends the API key
// (EventSource cannot), each resumed after the last event's id (docs/events.md). Only events from the page's
// start on are listed: the first streams only catch up with the outbox.
const RECENT_KEPT = 15;
const WARNING_KINDS = new Set(["curve_onset", "curve_level", "curve_release", "fcw"]);
const STREAM_WAIT_S = 1;
const STREAM_RETRY_MS = 2000;
const recentWarnings = [];
let lastEventId = null;

function listRecent() {
  const items = recentWarnings.map((e) => `<li><button data-vehicle="${escaped(e.vehicle_id)}">`
    + `${new Date(e.time * 1000).toLocaleTimeString()} · ${escaped(e.vehicle_id)} · ${escaped(e.kind)}`
    + ` · level ${e.level}${e.v_w_kmh == null ? "" : " · V_w " + e.v_w_kmh.toFixed(0) + " km/h"}</button></li>`);
  recentPanel.querySelector("#recent").innerHTML = items.join("");
  dataset.recentWarnings = String(recentWarnings.length);
}

// One frame of the stream: its id (the cursor) and its event, if it has data.
function takeFrame(frame, listed) {
  let data = null;
  for (const line of frame.split("\n")) {
    if (line.startsWith("id: ")) lastEventId = line.slice(4);
    else if (line.startsWith("data: ")) data = line.slice(6);
  }
  if (data === null || !listed) return;
  const event = JSON.parse(data);
  if (!WARNING_KINDS.has(event.kind) || (event.network !== null && event.network !== network.name)) return;
  recentWarnings.unshift(event);
  recentWarnings.length = Math.min(recentWarnings.length, RECENT_KEPT);
  listRecent();
}

// Read one stream to its end; with ``listed``, list its events (else it only catches up with the outbox).
async function readStream(listed) {
  const after = lastEventId === null ? "" : `&after=${encodeURIComponent(lastEventId)}`;
  const response = await fetch(`/v1/events?wait_s=${listed ? STREAM_WAIT_S : 0}${after}`, { headers: HEADERS });
  if (!response.ok) throw new Error(`/v1/events: HTTP ${response.status}`);
  (await response.text()).split("\n\n").forEach((frame) => takeFrame(frame, listed));
}

async function followEvents() {
  for (let listed = false; ; ) {
    try {
      const before = lastEventId;
      await readStream(listed);
      listed = listed || lastEventId === before;  // caught up: from now on every event is new
    } catch (error) {
      showStatus(error.message);
      await new Promise((resolve) => setTimeout(resolve, STREAM_RETRY_MS));
    }
  }
}

// The fleet's answer for the view: its vehicles and the service's time.

let fleetBusy = false;
let fleetUpdates = 0;
// The timing of the fleet's refreshes: the latest ones (when each started, since the page opened, how
// long its fetch, decode and marker update took, ms; how many vehicles it left), the ticks skipped
// because the refresh before was still running, and the refreshes that failed.
const fleetTimes = { refreshes: [], skipped: 0, failed: 0 };
// The vehicles in the view: every page of /v1/fleet for its bbox, following each page's next_cursor; the
// service's time of the first page (against which each vehicle's answered_at_s is aged) and the features.
async function fleetAnswer() {
  const query = `/v1/fleet?network=${encodeURIComponent(network.name)}&bbox=${viewBbox()}&limit=${FLEET_PAGE_SIZE}`;
  const features = [];
  let cursor = null;
  let generated_s = null;
  do {
    const data = await get(cursor === null ? query : `${query}&cursor=${encodeURIComponent(cursor)}`);
    generated_s ??= data.generated_s ?? null;
    features.push(...data.features);
    cursor = data.next_cursor;
  } while (cursor !== null && cursor !== undefined);
  return { generated_s, features };
}

async function loadFleet() {
  if (fleetBusy) {  // never queue requests behind a slow one: the next tick asks afresh
    fleetTimes.skipped++;
    return;
  }
  fleetBusy = true;
  const started = performance.now();
  try {
    const data = await fleetAnswer();
    fleetClock = { generated_s: data.generated_s ?? null, received_ms: performance.now() };
    const seen = new Set();
    for (const f of data.features) {
      if ((silenceS(f.properties) ?? 0) > GONE_AFTER_S) continue;
      seen.add(f.id);
      placeVehicle(f);
    }
    for (const [id, marker] of vehicles) {
      if (!seen.has(id)) { marker.remove(); vehicles.delete(id); }
    }
    if (selected && vehicles.has(selected) && !vehicles.get(selected).isPopupOpen() && !dataset.selectionShown) {
      dataset.selectionShown = "true";  // the vehicle named in the address, once it shows up
      select(selected);
    }
    listWarned();
    dataset.vehicles = String(vehicles.size);
    dataset.fleetUpdates = String(++fleetUpdates);
    const took_ms = performance.now() - started;
    dataset.fleetMs = took_ms.toFixed(1);
    fleetTimes.refreshes.push({ started_ms: started, took_ms: took_ms, vehicles: vehicles.size });
    if (fleetTimes.refreshes.length > REFRESHES_KEPT) fleetTimes.refreshes.shift();
    showStatus();
  } catch (error) {
    fleetTimes.failed++;
    showStatus(error.message);
  } finally {
    fleetBusy = false;
  }
}

// ---------------------------------------------------------------- panels

function showStatus(error) {
  const time = new Date().toLocaleTimeString();
  status.innerHTML = `<b>${escaped(network.name)}</b> · ${vehicles.size} vehicles · `
    + `${curves.getLayers().length} curves in view · ${time}` + (error ? `<br><span class="error">${escaped(error)}</span>` : "");
}

function shapeSvg(s) {
  const size = 2 * (s.radius + s.weight);
  return `<svg class="shape" width="${size}" height="${size}" viewBox="0 0 ${size} ${size}"><circle cx="${size / 2}" cy="${size / 2}" r="${s.radius}" `
    + `fill="${s.fillColor}" stroke="${s.color}" stroke-width="${s.weight}"`
    + `${s.dashArray ? ` stroke-dasharray="${s.dashArray}"` : ""}/></svg>`;
}

function legends() {
  const radii = RADIUS_CLASSES.map(([upTo, colour]) => `<div><svg class="swatch" width="18" height="6">`
    + `<line x1="0" y1="3" x2="18" y2="3" stroke="${colour}" stroke-width="5"/></svg>R ≤ ${upTo} m</div>`).join("");
  const states = Object.entries(VEHICLE_STYLES).map(([kind, style]) =>
    `<div>${shapeSvg(style)}${VEHICLE_LABELS[kind]}</div>`).join("");
  const options = NETWORKS.map((n) =>
    `<option${n.name === network.name ? " selected" : ""}>${escaped(n.name)}</option>`).join("");
  const legend = panel("topright", `<select id="network">${options}</select><h4>curves: minimum radius</h4>${radii}`
    + `<h4>vehicles</h4>${states}<div class="note">faded after ${FADE_AFTER_S} s without a fix, `
    + `gone after ${GONE_AFTER_S} s</div>`);
  legend.querySelector("#network").addEventListener("change", (event) => {
    location.href = "?network=" + encodeURIComponent(event.target.value) + (KEY ? "#key=" + encodeURIComponent(KEY) : "");
  });
}

function selectingList(position, html, list) {
  const div = panel(position, html);
  div.querySelector(list).addEventListener("click", (event) => {
    const button = event.target.closest("button[data-vehicle]");
    if (button) select(button.dataset.vehicle);
  });
  return div;
}

const warnedPanel = (() => {
  legends();
  return selectingList("topright", `<h4></h4><ol id="warned"></ol>`, "#warned");
})();
const recentPanel = selectingList("bottomright", `<h4>recent warnings</h4><ol id="recent"></ol>`, "#recent");

async function start() {
  try {
    const data = await get(`/v1/roads?network=${encodeURIComponent(network.name)}`);
    const drawn = L.geoJSON(data, { renderer: renderer, interactive: false, style: { color: "#8c8c8c", weight: 2 } });
    roads.addLayer(drawn);
    const view = addressedView();
    if (view) map.setView(view.centre, view.zoom);
    else map.fitBounds(drawn.getBounds(), { padding: [10, 10] });
    loadReport().catch((error) => showStatus(error.message));  // beside the curves, not before them
    map.on("zoomend", restyleCurves);
    map.on("moveend", () => { writeAddress(); loadCurves().catch((error) => showStatus(error.message)); });
    await loadCurves();
    dataset.ready = "true";
  } catch (error) {
    showStatus(error.message);
  }
  loadFleet();
  setInterval(loadFleet, FLEET_PERIOD_MS);
  followEvents();
}

window.cswsMap = {
  map: map, vehicles: vehicles, curves: curves, report: report, styles: VEHICLE_STYLES, fleetTimes: fleetTimes,
  radiusClasses: RADIUS_CLASSES, cityMetresPerPixel: CITY_METRES_PER_PIXEL, metresPerPixel: metresPerPixel,
  fadeAfterS: FADE_AFTER_S, goneAfterS: GONE_AFTER_S, select: select,
};
start();
