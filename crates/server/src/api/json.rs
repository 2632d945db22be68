//! A JSON body extractor whose failures are [`ApiError`]s in our shape,
//! with messages that say what is wrong (axum's own rejections are plain
//! text).

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{StatusCode, header};
use serde::de::DeserializeOwned;

use super::error::{ApiError, ErrorCode};

pub struct ApiJson<T>(pub T);

impl<S, T> FromRequest<S> for ApiJson<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, Self::Rejection> {
        if media_type(&req) != "application/json" && !media_type(&req).ends_with("+json") {
            return Err(ApiError::new(
                ErrorCode::UnsupportedMediaType,
                "send the body as JSON with `Content-Type: application/json`",
            ));
        }
        let bytes = read_body(req, state).await?;
        parse_json(&bytes).map(Self)
    }
}

/// The request's media type, lower case, without parameters ("" if none).
pub fn media_type(req: &Request) -> String {
    req.headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.split(';').next())
        .unwrap_or("")
        .trim()
        .to_ascii_lowercase()
}

/// The whole body, or 413 past the route's body limit.
pub async fn read_body<S: Send + Sync>(req: Request, state: &S) -> Result<Bytes, ApiError> {
    Bytes::from_request(req, state).await.map_err(|rejection| {
        if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::too_large("the request body is larger than the server accepts")
        } else {
            ApiError::malformed(format!(
                "cannot read the request body: {}",
                rejection.body_text()
            ))
        }
    })
}

/// A JSON body as `T`, with messages that say what is wrong.
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    serde_json::from_slice(bytes).map_err(|e| {
        let text = String::from_utf8_lossy(bytes);
        if e.is_syntax() && (text.contains("NaN") || text.contains("Infinity")) {
            ApiError::malformed(format!(
                "not valid JSON ({e}): JSON has no NaN or Infinity, every number must be finite"
            ))
        } else if e.is_syntax() || e.is_eof() {
            ApiError::malformed(format!("not valid JSON: {e}"))
        } else {
            // Valid JSON of the wrong shape: a missing or mistyped field.
            ApiError::malformed(format!("the request does not match the schema: {e}"))
        }
    })
}

/// Integer fields of request bodies. JSON Schema's `integer` admits a
/// number with a zero fraction (`3.0`) as well as `3`, and clients
/// (JavaScript, numpy) do send `3.0`; serde's integers would refuse it. These
/// accept both, and refuse fractions, negatives and values past 2⁵³ (where
/// an f64 stops being exact) with a message that says so.
pub mod integer {
    use serde::Deserialize;
    use serde::de::{self, Deserializer, Visitor};

    /// Largest integer every JSON number type represents exactly.
    const MAX_EXACT: f64 = 9_007_199_254_740_991.0;

    struct Integral(u64);

    impl<'de> Deserialize<'de> for Integral {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            struct V;
            impl Visitor<'_> for V {
                type Value = Integral;
                fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                    f.write_str("a non-negative integer")
                }
                fn visit_u64<E: de::Error>(self, v: u64) -> Result<Integral, E> {
                    Ok(Integral(v))
                }
                fn visit_i64<E: de::Error>(self, v: i64) -> Result<Integral, E> {
                    u64::try_from(v).map(Integral).map_err(|_| {
                        E::custom(format!(
                            "{v} is negative; a non-negative integer is expected"
                        ))
                    })
                }
                fn visit_f64<E: de::Error>(self, v: f64) -> Result<Integral, E> {
                    if v.fract() == 0.0 && (0.0..=MAX_EXACT).contains(&v) {
                        Ok(Integral(v as u64))
                    } else {
                        Err(E::custom(format!(
                            "{v} is not a non-negative integer (at most 2^53 - 1)"
                        )))
                    }
                }
            }
            d.deserialize_any(V)
        }
    }

    fn index(v: Integral) -> usize {
        usize::try_from(v.0).unwrap_or(usize::MAX)
    }

    pub fn usize<'de, D: Deserializer<'de>>(d: D) -> Result<usize, D::Error> {
        Integral::deserialize(d).map(index)
    }

    pub fn opt_usize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<usize>, D::Error> {
        Option::<Integral>::deserialize(d).map(|v| v.map(index))
    }

    pub fn opt_u64<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u64>, D::Error> {
        Option::<Integral>::deserialize(d).map(|v| v.map(|i| i.0))
    }

    pub fn vec_opt_usize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Option<usize>>, D::Error> {
        Vec::<Option<Integral>>::deserialize(d)
            .map(|v| v.into_iter().map(|i| i.map(index)).collect())
    }

    pub fn vec_usize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<usize>, D::Error> {
        Vec::<Integral>::deserialize(d).map(|v| v.into_iter().map(index).collect())
    }

    pub fn opt_vec_usize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<usize>>, D::Error> {
        Option::<Vec<Integral>>::deserialize(d)
            .map(|v| v.map(|v| v.into_iter().map(index).collect()))
    }
}
