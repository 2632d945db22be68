//! `GET /viewer`: a page that draws a tree, the forward model's prediction
//! beside the simulator's truth, the policy's affordances and a planned
//! arm motion. Its files (`assets/viewer/`) are embedded in the binary and
//! three.js is vendored (`scripts/vendor-three`), so the page works
//! offline; everything it computes comes from the API.

use axum::extract::Path;
use axum::http::header;
use axum::response::{IntoResponse, Response};

use super::error::ApiError;

/// One embedded file: its path below `/viewer/`, media type and bytes.
struct Asset {
    path: &'static str,
    media_type: &'static str,
    bytes: &'static [u8],
}

macro_rules! asset {
    ($path:literal, $media:literal) => {
        Asset {
            path: $path,
            media_type: $media,
            bytes: include_bytes!(concat!("../../../../assets/viewer/", $path)),
        }
    };
}

const ASSETS: [Asset; 10] = [
    asset!("index.html", "text/html; charset=utf-8"),
    asset!("viewer.js", "text/javascript; charset=utf-8"),
    asset!("api.js", "text/javascript; charset=utf-8"),
    asset!("cloud.js", "text/javascript; charset=utf-8"),
    asset!("meshes.js", "text/javascript; charset=utf-8"),
    asset!("viewer.css", "text/css; charset=utf-8"),
    asset!(
        "vendor/three.module.min.js",
        "text/javascript; charset=utf-8"
    ),
    asset!("vendor/OrbitControls.js", "text/javascript; charset=utf-8"),
    asset!("vendor/PLYLoader.js", "text/javascript; charset=utf-8"),
    asset!("vendor/LICENSE-three.txt", "text/plain; charset=utf-8"),
];

/// Only same-origin scripts, styles and API calls: the page never reaches
/// a CDN, and injected markup cannot run.
const CONTENT_SECURITY_POLICY: &str = "default-src 'self'; script-src 'self'; \
     style-src 'self'; img-src 'self' data: blob:; connect-src 'self'; object-src 'none'; \
     base-uri 'none'; frame-ancestors 'none'";

fn serve(asset: &Asset) -> Response {
    (
        [
            (header::CONTENT_TYPE, asset.media_type),
            (header::CONTENT_SECURITY_POLICY, CONTENT_SECURITY_POLICY),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        asset.bytes,
    )
        .into_response()
}

/// The browser viewer (HTML; its files under /viewer/).
///
/// Draws a tree, the forward model's prediction beside the simulator's
/// truth, the policy's affordances and a planned arm motion, using the
/// endpoints above. Its files are embedded in the server; it needs no
/// network.
#[utoipa::path(get, path = "/viewer", tag = "viewer",
    responses((status = 200, description = "The page.", body = String, content_type = "text/html")))]
pub async fn index() -> Response {
    serve(&ASSETS[0])
}

pub async fn asset(Path(file): Path<String>) -> Result<Response, ApiError> {
    let file = if file.is_empty() { "index.html" } else { &file };
    ASSETS
        .iter()
        .find(|a| a.path == file)
        .map(serve)
        .ok_or_else(|| ApiError::not_found(format!("the viewer has no file `{file}`")))
}
