//! Exact unit conversion between a gyro file's datasheet units and the simulator's and
//! fog-core's (deg/s, s): a value is read as the decimal written, divided by the unit's
//! integer factor exactly and rounded once to f64, so `turn_on_sigma_dph = 5.000004` is
//! `0.00138889` deg/s to the last bit, as if it had been written in deg/s. The writer
//! ([`write_exact`]) picks the shortest decimal that reads back to the value it was given.

/// deg/h per deg/s.
pub const DPH: f64 = 3600.0;
/// deg/sqrt(h) per deg/s/sqrt(Hz) (angle random walk).
pub const DEG_RTH: f64 = 60.0;
/// deg/h/sqrt(h) per deg/s/sqrt(s) (rate random walk).
pub const DPH_RTH: f64 = 216_000.0;
/// deg/h per h per deg/s per s (rate ramp).
pub const DPH_PER_H: f64 = 12_960_000.0;
/// deg/h per (deg C/min) per deg/s per (deg C/s) (temperature-rate link).
pub const DPH_PER_C_PER_MIN: f64 = 60.0;

/// Digits produced beyond the numerator's (then a sticky digit when the division does not
/// end): enough for the single rounding to f64 to be the rounding of the exact quotient.
const EXTRA_DIGITS: usize = 40;

/// The exact quotient `literal / factor` rounded once to f64. `literal` is a TOML integer or
/// float as written (`1_000.5`, `-3e-4`, `+7`); `factor` a positive integer (a unit factor).
/// `None` when the text is not a decimal number (`inf`, `nan`, hexadecimal) or the factor
/// not a positive integer: the caller divides in f64 then.
pub fn read_exact(literal: &str, factor: f64) -> Option<f64> {
    if factor == 1.0 {
        return literal.replace('_', "").parse().ok();
    }
    if !(factor >= 1.0 && factor.fract() == 0.0 && factor < 1e15) {
        return None;
    }
    let f = factor as u64;
    let text = literal.replace('_', "");
    let (neg, body) = match text.as_bytes().first()? {
        b'-' => (true, &text[1..]),
        b'+' => (false, &text[1..]),
        _ => (false, &text[..]),
    };
    let (mantissa, exp) = match body.find(['e', 'E']) {
        Some(i) => (&body[..i], body[i + 1..].parse::<i64>().ok()?),
        None => (body, 0),
    };
    let (int, frac) = mantissa.split_once('.').unwrap_or((mantissa, ""));
    if int.is_empty() && frac.is_empty() {
        return None;
    }
    if !int.bytes().chain(frac.bytes()).all(|b| b.is_ascii_digit()) {
        return None;
    }
    // value = digits x 10^(exp - frac.len())
    let digits: Vec<u8> = int.bytes().chain(frac.bytes()).map(|b| b - b'0').collect();
    let mut exp10 = exp.checked_sub(i64::try_from(frac.len()).ok()?)?;
    // Long division of the digit string by f: each step's remainder is below f.
    let mut quotient = String::with_capacity(digits.len() + EXTRA_DIGITS + 1);
    let mut rem: u64 = 0;
    for &d in &digits {
        rem = rem * 10 + u64::from(d);
        quotient.push(char::from(b'0' + (rem / f) as u8));
        rem %= f;
    }
    for _ in 0..EXTRA_DIGITS {
        rem *= 10;
        quotient.push(char::from(b'0' + (rem / f) as u8));
        rem %= f;
        exp10 -= 1;
    }
    if rem != 0 {
        // Sticky digit: the quotient goes on, so it is above the digits written so far.
        quotient.push('1');
        exp10 -= 1;
    }
    let v: f64 = format!("{}{quotient}e{exp10}", if neg { "-" } else { "" })
        .parse()
        .ok()?;
    Some(v)
}

/// The value in the file of `internal` (deg/s, ...) in a unit `factor` times larger, as
/// the shortest decimal `v` for which `accept(read_exact(v, factor))` holds (`accept`
/// tells the value the reader must give back: the same f64, or the same f32 once
/// rounded). Falls back to `internal * factor` printed in full when no decimal of up to
/// 21 significant digits reads back (not met in practice; tested on random values).
pub fn write_exact(internal: f64, factor: f64, accept: impl Fn(f64) -> bool) -> String {
    if !internal.is_finite() {
        return plain(&format!("{internal:e}"));
    }
    if internal == 0.0 {
        return "0.0".to_string();
    }
    let target = internal * factor;
    let ok = |s: &str| read_exact(s, factor).is_some_and(&accept);
    for p in 1..=17usize {
        let s = format!("{:.*e}", p - 1, target);
        if ok(&s) {
            return plain(&s);
        }
    }
    // Near the product: a few units of the last place either way at 17 to 21 digits.
    for p in 17..=21usize {
        let s = format!("{:.*e}", p - 1, target);
        let Some((m, e)) = s.split_once('e') else {
            break;
        };
        let neg = m.starts_with('-');
        let digits: String = m.chars().filter(char::is_ascii_digit).collect();
        let Ok(n) = digits.parse::<u128>() else {
            break;
        };
        let Ok(e) = e.parse::<i64>() else { break };
        for k in 1..=30u128 {
            for cand in [n + k, n.saturating_sub(k)] {
                let c = format!(
                    "{}{}e{}",
                    if neg { "-" } else { "" },
                    cand,
                    e - (p as i64 - 1)
                );
                if ok(&c) {
                    return plain(&c);
                }
            }
        }
    }
    plain(&format!("{target:e}"))
}

/// A decimal in scientific form (`1.5e0`, `123e-9`) as TOML likes to read it: plain
/// notation between 1e-5 and 1e15 (`1.5`, `0.000123`), else `1.23e-7`; always a float
/// (a `.` or an exponent).
pub fn plain(sci: &str) -> String {
    let Some((m, e)) = sci.split_once(['e', 'E']) else {
        return if sci.contains('.') || sci.contains("inf") || sci.contains("nan") {
            sci.to_string()
        } else {
            format!("{sci}.0")
        };
    };
    let Ok(e) = e.parse::<i64>() else {
        return sci.to_string();
    };
    let neg = m.starts_with('-');
    let (int, frac) = m
        .trim_start_matches(['-', '+'])
        .split_once('.')
        .unwrap_or((m.trim_start_matches(['-', '+']), ""));
    let mut digits: String = format!("{int}{frac}");
    // value = digits x 10^(e - frac.len())
    let mut point = int.len() as i64 + e; // position of the decimal point in `digits`
    let lead = digits.len() - digits.trim_start_matches('0').len();
    let removed = lead.min(digits.len().saturating_sub(1));
    digits.drain(..removed);
    point -= removed as i64;
    let digits = digits.trim_end_matches('0');
    let digits = if digits.is_empty() { "0" } else { digits };
    let sign = if neg { "-" } else { "" };
    let magnitude = point - 1; // exponent of the first digit
    if !(-5..15).contains(&magnitude) {
        let (first, rest) = digits.split_at(1);
        let rest = if rest.is_empty() { "0" } else { rest };
        return format!("{sign}{first}.{rest}e{magnitude}");
    }
    if point <= 0 {
        format!("{sign}0.{}{digits}", "0".repeat((-point) as usize))
    } else if point as usize >= digits.len() {
        format!(
            "{sign}{digits}{}.0",
            "0".repeat(point as usize - digits.len())
        )
    } else {
        let (a, b) = digits.split_at(point as usize);
        format!("{sign}{a}.{b}")
    }
}

/// `internal` rounded to `digits` significant digits in the file's unit (`factor` times
/// larger): the value the reader gives for that decimal (a fitted figure written without
/// its meaningless digits).
pub fn rounded(internal: f64, factor: f64, digits: usize) -> f64 {
    if internal == 0.0 || !internal.is_finite() || digits == 0 {
        return internal;
    }
    let text = format!("{:.*e}", digits - 1, internal * factor);
    read_exact(&text, factor).unwrap_or(internal)
}

/// `write_exact` for a value the reader must give back as the same f64.
pub fn write_f64(internal: f64, factor: f64) -> String {
    write_exact(internal, factor, |v| v == internal)
}

/// `write_exact` for a value the reader must give back as the same f32 (fog-core's
/// models are f32): the shortest decimal that rounds to it.
pub fn write_f32(internal: f32, factor: f64) -> String {
    write_exact(f64::from(internal), factor, |v| v as f32 == internal)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn reads_the_decimal_exactly() {
        // 5.000004 / 3600 is 0.00138889 exactly: the same f64 as the decimal 0.00138889,
        // which one f64 division does not give.
        assert_eq!(read_exact("5.000004", DPH), Some(0.00138889));
        assert_ne!(5.000004 / DPH, 0.00138889);
        assert_eq!(read_exact("0.0666666", DEG_RTH), Some(0.00111111));
        assert_eq!(read_exact("-1_000.5e-3", DPH), Some(-1.0005 / 3600.0));
        assert_eq!(read_exact("+36", DPH), Some(0.01));
        assert_eq!(read_exact("0", DPH), Some(0.0));
        assert_eq!(read_exact("1.5", 1.0), Some(1.5));
        assert_eq!(read_exact("inf", DPH), None);
        assert_eq!(read_exact("nan", DPH), None);
        assert_eq!(read_exact("0x10", DPH), None);
        // A thirds' quotient is rounded once: 1/3 of 1 deg/h x 3600.
        assert_eq!(read_exact("1200", DPH), Some(1.0 / 3.0));
    }

    #[test]
    fn writes_the_shortest_decimal_that_reads_back() {
        assert_eq!(write_f64(0.00138889, DPH), "5.000004");
        assert_eq!(write_f64(0.00111111, DEG_RTH), "0.0666666");
        assert_eq!(write_f64(2.31e-6, DPH_RTH), "0.49896");
        assert_eq!(write_f64(0.0, DPH), "0.0");
        assert_eq!(write_f64(-2.5, 1.0), "-2.5");
        assert_eq!(write_f64(1e-9, 1.0), "1.0e-9");
        assert_eq!(write_f64(3e20, 1.0), "3.0e20");
        assert_eq!(write_f64(100.0, 1.0), "100.0");
        assert_eq!(write_f32(0.067 / 60.0, DEG_RTH), "0.067");
        assert_eq!(
            write_f64(rounded(0.00833068849295217, DEG_RTH, 6), DEG_RTH),
            "0.499841"
        );
    }

    #[test]
    fn random_values_round_trip_bit_for_bit() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(44);
        for factor in [1.0, DEG_RTH, DPH, DPH_RTH, DPH_PER_H] {
            for _ in 0..2000 {
                let e: f64 = rng.random_range(-14.0..6.0);
                let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
                let x = sign * rng.random::<f64>() * 10f64.powf(e);
                let s = write_f64(x, factor);
                assert_eq!(read_exact(&s, factor), Some(x), "{x:e} x {factor}: {s}");
                let y = x as f32;
                if y != 0.0 && y.is_normal() {
                    let s = write_f32(y, factor);
                    let back = read_exact(&s, factor).map(|v| v as f32);
                    assert_eq!(back, Some(y), "{y:e} x {factor}: {s}");
                }
            }
        }
    }

    #[test]
    fn plain_notation() {
        assert_eq!(plain("1.5e0"), "1.5");
        assert_eq!(plain("1.23e-4"), "0.000123");
        assert_eq!(plain("1.23e-6"), "1.23e-6");
        assert_eq!(plain("-4.5e2"), "-450.0");
        assert_eq!(plain("123e-9"), "1.23e-7");
        assert_eq!(plain("7"), "7.0");
        assert_eq!(plain("2.0e14"), "200000000000000.0");
        assert_eq!(plain("2.0e15"), "2.0e15");
    }
}
