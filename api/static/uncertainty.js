// The one rule for a value with an uncertainty, as the certificate writes it
// (station/certificates/rounding.py format_with_uncertainty; a test compares the two on a table of
// cases): U to two significant digits, the value rounded to the decimal place of U's last digit
// (GUM 7.2.6), both in fixed notation, half-up on the shortest decimal representation.

// x as an integer of decimal digits and the power of ten of its last digit: x = n · 10^p.
function decimal(x) {
  const [m, e] = Math.abs(x).toExponential().split("e");
  const digits = m.replace(".", "");
  return { neg: x < 0, n: BigInt(digits), p: Number(e) - (digits.length - 1), top: Number(e) };
}

// d rounded half-up (ties away from zero) to a multiple of 10^place: the multiple's count.
function roundAt(d, place) {
  const shift = place - d.p;
  if (shift <= 0) return d.n * 10n ** BigInt(-shift);
  const unit = 10n ** BigInt(shift);
  const q = d.n / unit, rem = d.n % unit;
  return 2n * rem >= unit ? q + 1n : q;
}

function fixed(neg, q, place) {
  let s = q.toString();
  if (place >= 0) s = q === 0n ? "0" : s + "0".repeat(place);
  else {
    s = s.padStart(-place + 1, "0");
    s = `${s.slice(0, s.length + place)}.${s.slice(s.length + place)}`;
  }
  return neg && q !== 0n ? `-${s}` : s;
}

/** "value ± U" by the rule above; "–" when either is not a finite number. */
export function fmtU(value, U) {
  if (!Number.isFinite(value) || !Number.isFinite(U) || U < 0) return "–";
  if (U === 0) return `${reprNumber(value)} ± 0`;
  const u = decimal(U);
  let place = u.top - 1;
  let uq = roundAt(u, place);
  if (uq.toString().length > 2) { place += 1; uq = roundAt(u, place); }
  const v = decimal(value);
  return `${fixed(v.neg, roundAt(v, place), place)} ± ${fixed(false, uq, place)}`;
}

// Python's repr of a float (shortest digits; exponent with a sign and two digits; ".0" on integers).
function reprNumber(x) {
  const a = Math.abs(x);
  if (a !== 0 && (a < 1e-4 || a >= 1e16)) {
    const [m, e] = x.toExponential().split("e");
    const n = Number(e);
    return `${m}e${n < 0 ? "-" : "+"}${String(Math.abs(n)).padStart(2, "0")}`;
  }
  const s = String(x);
  return Number.isInteger(x) ? `${s}.0` : s;
}

/** [value, U] as fmtU writes them, for a table with separate columns (["–", "–"] when not finite). */
export function splitU(value, U) {
  const s = fmtU(value, U);
  return s === "–" ? ["–", "–"] : s.split(" ± ");
}
