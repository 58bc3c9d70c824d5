//! The fields of one box, each read and checked: class and score, stds or covariance, object
//! id and velocity, every error naming its field.

use super::*;

/// A box's class (`detection_name`) and score (`detection_score`).
pub(super) fn class_and_score(
    ctx: &Ctx,
    obj: &(impl BoxFields + ?Sized),
) -> Result<(Class, f64), JsonError> {
    let name = obj
        .field(Field::DetectionName)
        .ok_or_else(|| ctx.err(Some("detection_name"), "missing"))?;
    let name = name
        .as_str()
        .ok_or_else(|| ctx.err(Some("detection_name"), "expected a string"))?;
    let class = Class::from_name(name).ok_or_else(|| {
        ctx.err(
            Some("detection_name"),
            format!("unknown class '{name}' (expected a nuScenes detection class such as 'car')"),
        )
    })?;
    let score = match obj.field(Field::DetectionScore) {
        None => return Err(ctx.err(Some("detection_score"), "missing")),
        Some(v) => v
            .as_f64()
            .filter(|s| (0.0..=1.0).contains(s))
            .ok_or_else(|| ctx.err(Some("detection_score"), "expected a number in [0, 1]"))?,
    };
    Ok((class, score))
}

/// A box's stds, from its fields or, where it has none, the default `missing` gives.
pub(super) fn stds(
    ctx: &Ctx,
    obj: &(impl BoxFields + ?Sized),
    missing: MissingStd,
) -> Result<Uncertainty, JsonError> {
    let default = match missing {
        MissingStd::Default(u) => Some(u),
        MissingStd::Error => None,
    };
    let need = |field: &str| {
        ctx.err(
            Some(field),
            "missing (give the detector's stds, or a default with --default-std mild|moderate|large)",
        )
    };
    let pos = match ctx.numbers::<3>(obj, Field::TranslationStd)? {
        Some(p) => p,
        None => default.ok_or_else(|| need("translation_std"))?.pos,
    };
    let size = match ctx.numbers::<3>(obj, Field::SizeStd)? {
        Some([sw, sl, sh]) => [sl, sw, sh],
        None => default.ok_or_else(|| need("size_std"))?.size,
    };
    let yaw_std = match obj.field(Field::YawStd) {
        Some(v) => v
            .as_f64()
            .filter(|f| f.is_finite())
            .ok_or_else(|| ctx.err(Some("yaw_std"), "expected a number"))?,
        None => default.ok_or_else(|| need("yaw_std"))?.yaw,
    };
    let std = Uncertainty {
        pos,
        size,
        yaw: yaw_std,
    };
    if let Some(k) = std
        .as_array()
        .iter()
        .position(|s| !limits::std_in_range(*s))
    {
        let field = [
            "translation_std",
            "translation_std",
            "translation_std",
            "size_std",
            "size_std",
            "size_std",
            "yaw_std",
        ][k];
        return Err(ctx.err(Some(field), std_range_message()));
    }
    Ok(std)
}

/// A box's object id: its `instance_token` interned, else its `instance_id`, else none.
pub(super) fn object_id(
    ctx: &Ctx,
    obj: &(impl BoxFields + ?Sized),
    tokens: &mut TokenTable,
) -> Result<u32, JsonError> {
    let present = |f| obj.field(f).filter(|v| *v != FieldValue::Null);
    if let Some(v) = present(Field::InstanceToken) {
        return Ok(tokens.intern(
            v.as_str()
                .ok_or_else(|| ctx.err(Some("instance_token"), "expected a string"))?,
        ));
    }
    Ok(match present(Field::InstanceId) {
        Some(FieldValue::Number(_, Some(i))) if i < NO_ID as u64 => i as u32,
        Some(_) => return Err(ctx.err(Some("instance_id"), "expected an integer below 4294967295")),
        None => NO_ID,
    })
}

/// A box's velocity with its stds. A velocity counts only with its precision: without
/// `velocity_std` it is treated as absent (many detectors write [0, 0] when they do not
/// estimate it).
pub(super) fn velocity(
    ctx: &Ctx,
    obj: &(impl BoxFields + ?Sized),
) -> Result<Option<Velocity>, JsonError> {
    Ok(match ctx.numbers::<2>(obj, Field::VelocityStd)? {
        None => None,
        Some(sd) => {
            let v = ctx
                .numbers::<2>(obj, Field::Velocity)?
                .ok_or_else(|| ctx.err(Some("velocity"), "missing (velocity_std is given)"))?;
            if !v.iter().all(|x| limits::vel_in_range(*x)) {
                return Err(ctx.err(
                    Some("velocity"),
                    format!("must lie within {} m/s", limits::VEL_MAX),
                ));
            }
            if !sd.iter().all(|x| limits::std_in_range(*x)) {
                return Err(ctx.err(Some("velocity_std"), std_range_message()));
            }
            Some(Velocity { v, std: sd })
        }
    })
}

pub(super) fn std_range_message() -> String {
    format!(
        "standard deviations must lie in [{}, {:.0}] (metres or radians)",
        limits::STD_MIN,
        limits::std_max()
    )
}

/// Checks a row-major 3x3 covariance: symmetric, positive definite (it has a Cholesky factor),
/// and with every variance's std in the wire's std range.
pub(super) fn covariance(ctx: &Ctx, c: [f64; 9]) -> Result<[[f64; 3]; 3], JsonError> {
    let field = Some("translation_cov");
    let m = [[c[0], c[1], c[2]], [c[3], c[4], c[5]], [c[6], c[7], c[8]]];
    let sym =
        (0..3).all(|i| (0..3).all(|j| (m[i][j] - m[j][i]).abs() <= 1e-9 * (1.0 + m[i][j].abs())));
    if !sym {
        return Err(ctx.err(field, "expected a symmetric matrix"));
    }
    if !(0..3).all(|k| m[k][k] > 0.0 && limits::std_in_range(m[k][k].sqrt())) {
        return Err(ctx.err(field, std_range_message() + " on the diagonal"));
    }
    // Cholesky: every pivot of a positive-definite matrix is positive. A relative floor keeps
    // near-singular matrices (whose inverse would be meaningless) out too.
    let mut l = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                let pivot = m[i][i] - s;
                if !(pivot > 1e-12 * m[i][i]) {
                    return Err(ctx.err(
                        field,
                        "expected a positive-definite covariance (it has no Cholesky factor)",
                    ));
                }
                l[i][j] = pivot.sqrt();
            } else {
                l[i][j] = (m[i][j] - s) / l[j][j];
            }
        }
    }
    Ok(m)
}
