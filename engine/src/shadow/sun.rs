//! The sun: a direction and an RGB intensity.
//!
//! World axes are east-north-up (x east, y north, z up; the demo city's).
//! Azimuth is measured from north toward east, elevation up from the horizon.
//! The direction can also come from a UTC time and a latitude/longitude
//! through NOAA's solar-position formulas (the spreadsheet of the NOAA Global
//! Monitoring Laboratory, after Meeus), accurate to about 0.01° for years
//! 1800–2100 — the way driving datasets derive the sun from GPS time.

use glam::Vec3;

use crate::error::{Error, Result};

/// A directional light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Unit vector from the scene toward the sun.
    pub direction: Vec3,
    /// RGB irradiance scale.
    pub intensity: [f32; 3],
}

impl Sun {
    /// A sun toward `direction` (any non-zero length).
    pub fn from_direction(direction: Vec3, intensity: [f32; 3]) -> Result<Self> {
        let d = direction.normalize_or_zero();
        if d == Vec3::ZERO || !d.is_finite() {
            return Err(Error::invalid(format!("sun direction {direction}"), "is not a direction"));
        }
        check_intensity(intensity)?;
        Ok(Self { direction: d, intensity })
    }

    /// A sun at `azimuth` degrees from north toward east and `elevation`
    /// degrees above the horizon (negative: below it).
    pub fn from_azimuth_elevation(azimuth: f32, elevation: f32, intensity: [f32; 3]) -> Result<Self> {
        if !azimuth.is_finite() {
            return Err(Error::invalid(format!("sun azimuth {azimuth}°"), "must be finite"));
        }
        if !(-90.0..=90.0).contains(&elevation) {
            return Err(Error::invalid(format!("sun elevation {elevation}°"), "must be in [-90°, 90°]"));
        }
        let (az, el) = (f64::from(azimuth).to_radians(), f64::from(elevation).to_radians());
        let d = glam::DVec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin());
        Self::from_direction(d.as_vec3(), intensity)
    }

    /// (azimuth, elevation) in degrees.
    pub fn azimuth_elevation(&self) -> (f32, f32) {
        let d = self.direction;
        let azimuth = d.x.atan2(d.y).to_degrees().rem_euclid(360.0);
        (azimuth, d.z.clamp(-1.0, 1.0).asin().to_degrees())
    }

    /// Whether the sun is above the horizon (below it gives no sun light).
    pub fn above_horizon(&self) -> bool {
        self.direction.z > 0.0
    }
}

/// Largest sun irradiance per channel accepted (far above any real sun in
/// srug's units, low enough that shading and exposure stay finite in f32).
pub const MAX_SUN_INTENSITY: f32 = 1.0e9;

fn check_intensity(intensity: [f32; 3]) -> Result<()> {
    if intensity.iter().all(|v| v.is_finite() && *v >= 0.0 && *v <= MAX_SUN_INTENSITY) {
        Ok(())
    } else {
        let [r, g, b] = intensity;
        Err(Error::invalid(format!("sun intensity {r}, {g}, {b}"), format!("must be in 0..={MAX_SUN_INTENSITY:e}")))
    }
}

/// A UTC date and time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UtcTime {
    /// Year (Gregorian).
    pub year: i32,
    /// Month 1–12.
    pub month: u32,
    /// Day of the month 1–31.
    pub day: u32,
    /// Seconds since midnight UTC.
    pub seconds: f64,
}

impl UtcTime {
    /// Parses ISO 8601 `YYYY-MM-DDTHH:MM[:SS[.fff]]` followed by `Z` or an
    /// offset `±HH:MM` (a space may replace the `T`).
    pub fn parse(text: &str) -> Result<Self> {
        let bad = |why: &str| {
            Error::invalid(
                format!("time \"{text}\""),
                format!("{why} (expected e.g. 2024-06-21T12:30:00Z or 2024-06-21T14:30+02:00)"),
            )
        };
        let t = text.trim();
        let (date, rest) = t.split_once(['T', ' ']).ok_or_else(|| bad("has no time part"))?;
        let mut d = date.split('-');
        let (year, month, day) = match (d.next(), d.next(), d.next(), d.next()) {
            (Some(y), Some(m), Some(dd), None) => (
                y.parse::<i32>().map_err(|_| bad("has a bad year"))?,
                m.parse::<u32>().map_err(|_| bad("has a bad month"))?,
                dd.parse::<u32>().map_err(|_| bad("has a bad day"))?,
            ),
            _ => return Err(bad("has a bad date")),
        };
        let (clock, offset_minutes) = if let Some(c) = rest.strip_suffix('Z') {
            (c, 0.0)
        } else if let Some(i) = rest.rfind(['+', '-']) {
            let (c, off) = rest.split_at(i);
            let sign = if off.starts_with('-') { -1.0 } else { 1.0 };
            let (h, m) = off[1..].split_once(':').ok_or_else(|| bad("has a bad offset"))?;
            let h: f64 = h.parse().map_err(|_| bad("has a bad offset"))?;
            let m: f64 = m.parse().map_err(|_| bad("has a bad offset"))?;
            (c, sign * (h * 60.0 + m))
        } else {
            return Err(bad("has no time zone (add Z for UTC)"));
        };
        let parts: Vec<&str> = clock.split(':').collect();
        if !(2..=3).contains(&parts.len()) {
            return Err(bad("has a bad clock time"));
        }
        let num = |s: &str| s.parse::<f64>().ok().filter(|v| v.is_finite() && *v >= 0.0);
        let h = num(parts[0]).filter(|v| *v < 24.0).ok_or_else(|| bad("has a bad hour"))?;
        let m = num(parts[1]).filter(|v| *v < 60.0).ok_or_else(|| bad("has a bad minute"))?;
        let s =
            parts.get(2).map_or(Some(0.0), |s| num(s).filter(|v| *v < 61.0)).ok_or_else(|| bad("has bad seconds"))?;
        let days_in_month = match month {
            1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
            4 | 6 | 9 | 11 => 30,
            2 if (year % 4 == 0 && year % 100 != 0) || year % 400 == 0 => 29,
            2 => 28,
            _ => return Err(bad("has a month outside 1-12")),
        };
        if day == 0 || day > days_in_month {
            return Err(bad("has a day outside its month"));
        }
        let local = Self { year, month, day, seconds: h * 3600.0 + m * 60.0 + s };
        Ok(local.shifted(-offset_minutes * 60.0))
    }

    /// Julian date.
    pub fn julian_date(&self) -> f64 {
        2_440_587.5 + self.days_since_1970() as f64 + self.seconds / 86_400.0
    }

    /// Whole days from 1970-01-01 to this date (H. Hinnant's days_from_civil).
    fn days_since_1970(&self) -> i64 {
        let y = i64::from(self.year) - i64::from(self.month <= 2);
        let era = y.div_euclid(400);
        let yoe = y - era * 400;
        let m = i64::from(self.month);
        let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(self.day) - 1;
        let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
        era * 146_097 + doe - 719_468
    }

    /// The same instant `seconds` later, carrying whole days into the date.
    pub fn shifted(self, seconds: f64) -> Self {
        let total = self.seconds + seconds;
        let carry = (total / 86_400.0).floor();
        let mut t = from_days_since_1970(self.days_since_1970() + carry as i64);
        t.seconds = total - carry * 86_400.0;
        t
    }
}

/// `frames` evenly spaced instants from `start` to `end` (inclusive; one
/// frame gives `start`) and the sun's position at each, seen from
/// `latitude`, `longitude`: the sun path of a time-lapse.
pub fn sun_path(
    start: &UtcTime,
    end: &UtcTime,
    frames: u32,
    latitude: f64,
    longitude: f64,
) -> Result<Vec<(UtcTime, SolarPosition)>> {
    let span = (end.julian_date() - start.julian_date()) * 86_400.0;
    if frames == 0 || !(0.0..=366.0 * 86_400.0).contains(&span) {
        return Err(Error::invalid(
            format!("sun path of {frames} frames over {span:.0} s"),
            "needs at least one frame and an end within a year after its start",
        ));
    }
    (0..frames)
        .map(|i| {
            let t = start.shifted(if frames == 1 { 0.0 } else { span * f64::from(i) / f64::from(frames - 1) });
            solar_position(&t, latitude, longitude).map(|p| (t, p))
        })
        .collect()
}

/// The date `days` after 1970-01-01 at midnight (civil_from_days).
fn from_days_since_1970(days: i64) -> UtcTime {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = (yoe + era * 400 + i64::from(month <= 2)) as i32;
    UtcTime { year, month, day, seconds: 0.0 }
}

/// Where the sun is in the sky.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolarPosition {
    /// Degrees from north toward east.
    pub azimuth: f64,
    /// Degrees above the horizon, without atmospheric refraction.
    pub elevation: f64,
}

/// The sun's position at `time` seen from `latitude`, `longitude` (degrees,
/// east positive), by NOAA's formulas.
pub fn solar_position(time: &UtcTime, latitude: f64, longitude: f64) -> Result<SolarPosition> {
    if !(-90.0..=90.0).contains(&latitude) || !(-180.0..=360.0).contains(&longitude) {
        return Err(Error::invalid(format!("latitude {latitude}° / longitude {longitude}°"), "is not on Earth"));
    }
    let jc = (time.julian_date() - 2_451_545.0) / 36_525.0;
    let l0 = (280.466_46 + jc * (36_000.769_83 + jc * 0.000_303_2)).rem_euclid(360.0);
    let m = 357.529_11 + jc * (35_999.050_29 - 0.000_153_7 * jc);
    let e = 0.016_708_634 - jc * (0.000_042_037 + 0.000_000_126_7 * jc);
    let mr = m.to_radians();
    let centre = mr.sin() * (1.914_602 - jc * (0.004_817 + 0.000_014 * jc))
        + (2.0 * mr).sin() * (0.019_993 - 0.000_101 * jc)
        + (3.0 * mr).sin() * 0.000_289;
    let omega = (125.04 - 1934.136 * jc).to_radians();
    let apparent_longitude = (l0 + centre - 0.005_69 - 0.004_78 * omega.sin()).to_radians();
    let mean_obliquity = 23.0 + (26.0 + (21.448 - jc * (46.815 + jc * (0.000_59 - jc * 0.001_813))) / 60.0) / 60.0;
    let obliquity = (mean_obliquity + 0.002_56 * omega.cos()).to_radians();
    let declination = (obliquity.sin() * apparent_longitude.sin()).asin();
    let y = (obliquity / 2.0).tan().powi(2);
    let l0r = l0.to_radians();
    let equation_of_time = 4.0
        * (y * (2.0 * l0r).sin() - 2.0 * e * mr.sin() + 4.0 * e * y * mr.sin() * (2.0 * l0r).cos()
            - 0.5 * y * y * (4.0 * l0r).sin()
            - 1.25 * e * e * (2.0 * mr).sin())
        .to_degrees();
    let true_solar_minutes = (time.seconds / 60.0 + equation_of_time + 4.0 * longitude).rem_euclid(1440.0);
    let hour_angle = true_solar_minutes / 4.0 - 180.0;
    let (lat, ha) = (latitude.to_radians(), hour_angle.to_radians());
    let cos_zenith = (lat.sin() * declination.sin() + lat.cos() * declination.cos() * ha.cos()).clamp(-1.0, 1.0);
    let zenith = cos_zenith.acos();
    let denominator = lat.cos() * zenith.sin();
    let azimuth = if denominator.abs() < 1e-12 {
        // At a pole or with the sun at the zenith the azimuth is undefined; take 180°.
        180.0
    } else {
        let a = ((lat.sin() * zenith.cos() - declination.sin()) / denominator).clamp(-1.0, 1.0).acos().to_degrees();
        if hour_angle > 0.0 {
            (a + 180.0).rem_euclid(360.0)
        } else {
            (540.0 - a).rem_euclid(360.0)
        }
    };
    Ok(SolarPosition { azimuth, elevation: 90.0 - zenith.to_degrees() })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    /// A bad angle is blamed on itself, not on the other one.
    #[test]
    fn bad_angles_are_named() {
        let e = Sun::from_azimuth_elevation(f32::NAN, 30.0, [1.0; 3]).unwrap_err().to_string();
        assert!(e.contains("sun azimuth NaN") && !e.contains("elevation"), "{e}");
        let e = Sun::from_azimuth_elevation(10.0, 95.0, [1.0; 3]).unwrap_err().to_string();
        assert!(e.contains("sun elevation 95") && !e.contains("azimuth"), "{e}");
        // An intensity that would overflow shading in f32 is refused.
        let e = Sun::from_azimuth_elevation(10.0, 30.0, [1.0, 1e10, 1.0]).unwrap_err().to_string();
        assert!(e.contains("sun intensity 1, 10000000000, 1") && e.contains("0..=1e9"), "{e}");
        assert!(Sun::from_azimuth_elevation(10.0, 30.0, [MAX_SUN_INTENSITY; 3]).is_ok());
    }

    #[test]
    fn nrel_spa_reference_position() {
        // NREL SPA report (Reda & Andreas 2008) example: 2003-10-17 12:30:30 at UTC−7,
        // 39.742476° N, 105.1786° W: topocentric zenith 50.11162° (refraction included,
        // about 0.02° at this height), azimuth 194.34024°. NOAA is within ~0.05°.
        let t = UtcTime::parse("2003-10-17T12:30:30-07:00").unwrap();
        assert_eq!((t.year, t.month, t.day), (2003, 10, 17));
        assert!((t.seconds - (19.0 * 3600.0 + 30.0 * 60.0 + 30.0)).abs() < 1e-6);
        let p = solar_position(&t, 39.742_476, -105.1786).unwrap();
        assert!((90.0 - p.elevation - 50.111_62).abs() < 0.06, "zenith {}", 90.0 - p.elevation);
        assert!((p.azimuth - 194.340_24).abs() < 0.06, "azimuth {}", p.azimuth);
    }

    #[test]
    fn julian_dates_and_offsets() {
        assert_eq!(UtcTime::parse("2000-01-01T12:00:00Z").unwrap().julian_date(), 2_451_545.0);
        let a = UtcTime::parse("2024-03-01T00:30+01:00").unwrap();
        assert_eq!((a.year, a.month, a.day), (2024, 2, 29));
        assert!((a.seconds - (23.0 * 3600.0 + 1800.0)).abs() < 1e-6);
        for bad in ["2024-02-30T00:00Z", "2024-13-01T00:00Z", "2024-01-01T25:00Z", "2024-01-01T10:00", "noon"] {
            assert!(UtcTime::parse(bad).is_err(), "{bad} parsed");
        }
    }

    #[test]
    fn azimuth_elevation_round_trip_and_horizon() {
        for (az, el) in [(0.0, 45.0), (90.0, 0.01), (200.0, 89.0), (359.0, -5.0)] {
            let s = Sun::from_azimuth_elevation(az, el, [1.0; 3]).unwrap();
            let (a, e) = s.azimuth_elevation();
            assert!((a - az).abs() < 1e-3 && (e - el).abs() < 1e-3, "{az} {el} -> {a} {e}");
            assert_eq!(s.above_horizon(), el > 0.0);
        }
        let east = Sun::from_azimuth_elevation(90.0, 0.0, [1.0; 3]).unwrap();
        assert!((east.direction - Vec3::X).length() < 1e-6);
        assert!(Sun::from_azimuth_elevation(0.0, 91.0, [1.0; 3]).is_err());
        assert!(Sun::from_direction(Vec3::ZERO, [1.0; 3]).is_err());
        assert!(Sun::from_direction(Vec3::Z, [f32::NAN, 1.0, 1.0]).is_err());
    }

    #[test]
    fn equinox_noon_at_the_equator_is_overhead() {
        // 2024-03-20 03:06 UTC equinox; at local solar noon on the equator the sun is within
        // a degree of the zenith the same day.
        let t = UtcTime::parse("2024-03-20T12:07:00Z").unwrap();
        let p = solar_position(&t, 0.0, 0.0).unwrap();
        assert!(p.elevation > 89.0, "elevation {}", p.elevation);
        // Midnight: well below the horizon.
        let night = solar_position(&UtcTime::parse("2024-03-20T00:07:00Z").unwrap(), 0.0, 0.0).unwrap();
        assert!(night.elevation < -80.0);
    }
}
