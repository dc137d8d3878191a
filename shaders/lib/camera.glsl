// Pinhole camera math. Binding-free: pure functions of their arguments.
// Image points are in pixels, origin at the top-left corner, y down; a pixel's centre is
// (x + 0.5, y + 0.5). The camera basis (right, up, forward) is orthonormal.
#ifndef CAMERA_GLSL
#define CAMERA_GLSL

// Unit direction of the ray through image point `p` of a `size` image.
vec3 pinhole_direction(vec3 right, vec3 up, vec3 forward, float tan_half_fov, float aspect, vec2 p, vec2 size) {
    vec2 ndc = vec2(2.0 * p.x / size.x - 1.0, 1.0 - 2.0 * p.y / size.y);
    vec2 s = ndc * tan_half_fov * vec2(aspect, 1.0);
    return normalize(forward + s.x * right + s.y * up);
}

// Inverse of pinhole_direction: the image point where world point `x` appears (xy) and its view
// depth along `forward` (z; z <= 0 behind the camera, and xy is then meaningless).
vec3 pinhole_project(vec3 eye, vec3 right, vec3 up, vec3 forward, float tan_half_fov, float aspect, vec3 x, vec2 size) {
    vec3 d = x - eye;
    float z = dot(d, forward);
    vec2 ndc = vec2(dot(d, right) / (aspect * tan_half_fov), dot(d, up) / tan_half_fov) / max(z, 1e-30);
    return vec3(0.5 * (ndc.x + 1.0) * size.x, 0.5 * (1.0 - ndc.y) * size.y, z);
}

// Whether a previous frame's surface (normal n_prev, view depth depth_prev in the previous camera)
// is the same surface as this frame's point (normal n, view depth `depth` in the previous camera):
// the tests spatial reuse applies to its neighbours (cosine of normals at least normal_threshold,
// relative depth difference at most depth_threshold).
bool same_surface(vec3 n, float depth, vec3 n_prev, float depth_prev, float normal_threshold, float depth_threshold) {
    return depth_prev > 0.0 && dot(n, n_prev) >= normal_threshold
        && abs(depth_prev - depth) <= depth_threshold * depth;
}

#endif
