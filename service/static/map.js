// The live map of csws (GET /map): the roads of one served network, its curves in the view coloured
// by minimum radius, and the live vehicles, asked for once a second; where the network has a map report
// (GET /v1/report), a layer of what its map shows wrong or doubtful, off until ticked. No tiles: it works offline.
// Address: /map?network=NAME#key=API_KEY (both optional).
"use strict";

const NETWORKS = JSON.parse(document.getElementById("networks").textContent);
const KEY = (location.hash.match(/key=([^&]+)/) || [])[1];
const HEADERS = KEY ? { Authorization: "Bearer " + decodeURIComponent(KEY) } : {};
const FLEET_PERIOD_MS = 1000;
// Vehicles per request of /v1/fleet: the service's largest page (service.fleet.MAX_PAGE_SIZE).
const FLEET_PAGE_SIZE = 10000;
// How many of the latest fleet refreshes the page keeps the timing of (for benchmarks/map.py).
const REFRESHES_KEPT = 120;

// Curves: upper bound of minimum radius (m) and colour, sharpest first; R_c = 300 m (3.2).
const RADIUS_CLASSES = [[40, "#800026"], [80, "#bd0026"], [120, "#e31a1c"], [200, "#fc4e2a"], [300, "#fd8d3c"]];
// Vehicles: system state (5.2-5.4), and the warning level when active (6.1).
const VEHICLE_COLOURS = {
  off: "#9e9e9e", standby: "#1f78b4", fault: "#222222",
  "active-0": "#33a02c", "active-1": "#ff9900", "active-2": "#e31a1c",
};
// The map report: colour of each kind of item (csws.osm.report.KINDS).
const REPORT_COLOURS = {
  "artefact-spike": "#6a3d9a", "artefact-fold": "#6a3d9a", "artefact-jog": "#6a3d9a", "artefact-zigzag": "#6a3d9a",
  "floor-curve": "#b15928", "single-node-corner": "#1f78b4", "border-cut": "#000000", dropped: "#737373",
};
const VEHICLE_LABELS = {
  off: "off", standby: "standby", fault: "fault",
  "active-0": "active, no warning", "active-1": "level 1 warning", "active-2": "level 2 warning",
};

const chosen = new URLSearchParams(location.search).get("network")
  || (NETWORKS.find((n) => n.geo_referenced) || NETWORKS[0]).name;
const network = NETWORKS.find((n) => n.name === chosen) || NETWORKS[0];
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

function panel(position, html) {
  const control = L.control({ position: position });
  control.onAdd = () => { const div = L.DomUtil.create("div", "panel"); div.innerHTML = html; return div; };
  control.addTo(map);
  L.DomEvent.disableClickPropagation(control.getContainer());
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

function radiusColour(radius_m) {
  const found = RADIUS_CLASSES.find(([upTo]) => radius_m <= upTo);
  return (found || RADIUS_CLASSES[RADIUS_CLASSES.length - 1])[1];
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
  dataset.reportFeatures = String(data.features.length);
}

function vehicleKind(p) {
  return p.state === "active" ? `active-${p.level}` : p.state;
}

function vehiclePopup(p) {
  return `<b>${escaped(p.vehicle_id)}</b> (${escaped(p.category)})<br>${VEHICLE_LABELS[vehicleKind(p)]}`
    + `${p.fault ? ": " + escaped(p.fault) : ""}<br>${p.speed_kmh.toFixed(1)} km/h on ${escaped(p.lane_id)}`;
}

function showStatus(error) {
  const time = new Date().toLocaleTimeString();
  status.innerHTML = `<b>${escaped(network.name)}</b> · ${vehicles.size} vehicles · `
    + `${curves.getLayers().length} curves in view · ${time}` + (error ? `<br><span style="color:#c00">${escaped(error)}</span>` : "");
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
    style: (f) => ({ color: radiusColour(f.properties.radius_m), weight: 5, opacity: 0.9 }),
    onEachFeature: (f, layer) => { layer.bindPopup(() => curvePopup(f.properties)); curves.addLayer(layer); },
  });
  dataset.curvesBbox = bbox;
  dataset.curvesDrawn = String(curves.getLayers().length);
  showStatus();
}

let fleetBusy = false;
let fleetUpdates = 0;
// The timing of the fleet's refreshes: the latest ones (when each started, since the page opened, how
// long its fetch, decode and marker update took, ms; how many vehicles it left), the ticks skipped
// because the refresh before was still running, and the refreshes that failed.
const fleetTimes = { refreshes: [], skipped: 0, failed: 0 };
// The vehicles in the view: every page of /v1/fleet for its bbox, following each page's next_cursor.
async function fleetInView() {
  const query = `/v1/fleet?network=${encodeURIComponent(network.name)}&bbox=${viewBbox()}&limit=${FLEET_PAGE_SIZE}`;
  const features = [];
  let cursor = null;
  do {
    const data = await get(cursor === null ? query : `${query}&cursor=${encodeURIComponent(cursor)}`);
    features.push(...data.features);
    cursor = data.next_cursor;
  } while (cursor !== null && cursor !== undefined);
  return features;
}

async function loadFleet() {
  if (fleetBusy) {  // never queue requests behind a slow one: the next tick asks afresh
    fleetTimes.skipped++;
    return;
  }
  fleetBusy = true;
  const started = performance.now();
  try {
    const features = await fleetInView();
    const seen = new Set();
    for (const f of features) {
      const p = f.properties;
      const [x, y] = f.geometry.coordinates;
      const colour = VEHICLE_COLOURS[vehicleKind(p)];
      seen.add(f.id);
      let marker = vehicles.get(f.id);
      if (marker === undefined) {
        marker = L.circleMarker([y, x], { renderer: renderer, radius: 5, weight: 1, color: "#fff", fillOpacity: 1, fillColor: colour });
        marker.bindPopup(() => vehiclePopup(marker.properties));
        vehicles.set(f.id, marker.addTo(map));
      } else {
        marker.setLatLng([y, x]);
        if (marker.options.fillColor !== colour) marker.setStyle({ fillColor: colour });
      }
      marker.properties = p;
    }
    for (const [id, marker] of vehicles) {
      if (!seen.has(id)) { marker.remove(); vehicles.delete(id); }
    }
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

function legends() {
  const radii = RADIUS_CLASSES.map(([upTo, colour]) =>
    `<div><span class="swatch" style="background:${colour}"></span>R ≤ ${upTo} m</div>`).join("");
  const states = Object.entries(VEHICLE_COLOURS).map(([kind, colour]) =>
    `<div><span class="dot" style="background:${colour}"></span>${VEHICLE_LABELS[kind]}</div>`).join("");
  const options = NETWORKS.map((n) =>
    `<option${n.name === network.name ? " selected" : ""}>${escaped(n.name)}</option>`).join("");
  const legend = panel("topright", `<select id="network">${options}</select><h4>curves: minimum radius</h4>${radii}`
    + `<h4>vehicles</h4>${states}`);
  legend.querySelector("#network").addEventListener("change", (event) => {
    location.search = "?network=" + encodeURIComponent(event.target.value);
  });
}

async function start() {
  legends();
  try {
    const data = await get(`/v1/roads?network=${encodeURIComponent(network.name)}`);
    const drawn = L.geoJSON(data, { renderer: renderer, interactive: false, style: { color: "#8c8c8c", weight: 2 } });
    roads.addLayer(drawn);
    map.fitBounds(drawn.getBounds(), { padding: [10, 10] });
    loadReport().catch((error) => showStatus(error.message));  // beside the curves, not before them
    map.on("moveend", () => loadCurves().catch((error) => showStatus(error.message)));
    await loadCurves();
    dataset.ready = "true";
  } catch (error) {
    showStatus(error.message);
  }
  loadFleet();
  setInterval(loadFleet, FLEET_PERIOD_MS);
}

window.cswsMap = {
  map: map, vehicles: vehicles, curves: curves, report: report, colours: VEHICLE_COLOURS, fleetTimes: fleetTimes,
};
start();
