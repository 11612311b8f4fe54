// Colour ramps and the legend.

// A perceptual ramp (close to viridis), from dark blue through green to yellow.
const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
// Few changes to many: cool grey-blue to hot red.
const HEAT = [[70, 90, 130], [60, 150, 220], [250, 210, 60], [240, 90, 40], [200, 20, 40]];

function ramp(stops, t) {
  const x = Math.min(1, Math.max(0, t)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(x));
  const f = x - i;
  return stops[i].map((v, k) => v + (stops[i + 1][k] - v) * f);
}
export const viridis = (t) => ramp(VIRIDIS, t);
export const heat = (t) => ramp(HEAT, t);

export function gradientCss(fn) {
  const parts = [];
  for (let i = 0; i <= 8; ++i) parts.push(`rgb(${fn(i / 8).map(Math.round).join(',')}) ${(i / 8) * 100}%`);
  return `linear-gradient(90deg, ${parts.join(', ')})`;
}

export const APPEARED = [60, 207, 110];
export const VANISHED = [255, 90, 90];
// A moved object: where it is now, and (paler) where it stood.
export const MOVED = [255, 176, 32];
export const MOVED_FROM = [214, 196, 160];
export const css = (c) => `rgb(${c.map(Math.round).join(',')})`;
