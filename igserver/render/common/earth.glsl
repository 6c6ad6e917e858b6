// The earth's surface seen from a camera at height H above it: a sphere of radius R whose centre is
// at (0, 0, -(R + H)) camera-relative (the horizon dips and the surface ends there). Distance along
// the unit ray dir to it, or -1 when the ray misses it: solve t^2 - 2 b t + C = 0 with b = d.c =
// -(R + H) d_z and C = |c|^2 - R^2 = H (2R + H), written without the cancellation of |c|^2 - R^2,
// and take the near root as C / (b + sqrt(b^2 - C)).
const float EARTH_SPHERE_RADIUS = 6.371e6;  // m

float earth_sphere_distance(vec3 dir, float H) {
    float b = -(EARTH_SPHERE_RADIUS + H) * dir.z;
    float C = H * (2.0 * EARTH_SPHERE_RADIUS + H);
    float disc = b * b - C;
    if (b <= 0.0 || disc < 0.0) return -1.0;
    return C / (b + sqrt(disc));
}
