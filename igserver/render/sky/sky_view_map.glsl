// Sky-view table map (Hillaire 2020, "A Scalable and Production Ready Sky and Atmosphere Rendering
// Technique", section 5.3): a clear sky seen from one point is symmetric about the sun's vertical,
// so the table is indexed by
//   u = phi / pi,   phi the azimuth from the sun (0 toward it, pi away; either side),
//   v = 1/2 +- 1/2 sqrt(|e - e_h| / (pi/2 +- e_h)),   e the elevation, e_h the horizon's (the dip),
// which packs rows toward the horizon, where the sky changes fastest, and puts the horizon exactly
// on the seam between two rows (lookups clamp to their side: no blur across it).
uniform vec2 u_sky_view_sun_h;      // unit horizontal direction toward the sun (any if at the zenith)
uniform float u_horizon_elevation;  // rad, elevation of the geometric horizon (<= 0, the dip)

vec2 sky_view_uv_sized(vec3 dir, vec2 size) {
    vec2 h = dir.xy;
    float lh = length(h);
    float cos_phi = lh > 1e-7 ? dot(h / lh, u_sky_view_sun_h) : 1.0;
    float u = acos(clamp(cos_phi, -1.0, 1.0)) / 3.14159265358979;
    float e = asin(clamp(dir.z, -1.0, 1.0));
    float eh = u_horizon_elevation;
    float v;
    if (e >= eh) {
        v = 0.5 + 0.5 * sqrt(clamp((e - eh) / (1.5707963268 - eh), 0.0, 1.0));
        v = max(v, 0.5 + 0.5 / size.y);
    } else {
        v = 0.5 - 0.5 * sqrt(clamp((eh - e) / (eh + 1.5707963268), 0.0, 1.0));
        v = min(v, 0.5 - 0.5 / size.y);
    }
    return vec2(u, v);
}

// Inverse map, for the texel centres of the table.
vec3 sky_view_dir(vec2 uv) {
    float phi = uv.x * 3.14159265358979;
    float eh = u_horizon_elevation;
    float e;
    if (uv.y >= 0.5) {
        float x = 2.0 * uv.y - 1.0;
        e = eh + x * x * (1.5707963268 - eh);
    } else {
        float x = 1.0 - 2.0 * uv.y;
        e = eh - x * x * (eh + 1.5707963268);
    }
    vec2 perp = vec2(-u_sky_view_sun_h.y, u_sky_view_sun_h.x);
    vec2 h = cos(phi) * u_sky_view_sun_h + sin(phi) * perp;
    return vec3(cos(e) * h, sin(e));
}
