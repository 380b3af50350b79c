"""GLSL 3.30 sources for the renderer: a depth-only shadow pass, lit meshes and the floor.

Lighting is computed in linear RGB and written as sRGB; colours given to the
shaders as uniforms or vertex attributes are sRGB in [0, 1].
"""

SHADOW_VS = """
#version 330
uniform mat4 u_light_vp;
in vec3 in_pos;
void main() { gl_Position = u_light_vp * vec4(in_pos, 1.0); }
"""

SHADOW_FS = """
#version 330
void main() {}
"""

# Shared by the mesh and floor fragment shaders: colour space and soft shadow lookup.
_COMMON = """
uniform sampler2DShadow u_shadow_map;
uniform mat4 u_light_vp;
uniform int u_shadows;          // 0: no shadows
uniform float u_shadow_texel;   // 1 / shadow map size
uniform float u_shadow_bias;    // world-space offset along the normal, metres

// 12 Poisson-disc taps, each a hardware-filtered 2x2 comparison. The first 4 are spread
// around the disc: when they agree (fully lit or fully shadowed, most pixels) the rest
// are skipped, which matters on software GL where MSAA shades every sample.
const vec2 POISSON[12] = vec2[](
    vec2(-0.94201624, -0.39906216), vec2(0.94558609, -0.76890725),
    vec2(-0.24188840, 0.99706507), vec2(0.97484398, 0.75648379),
    vec2(-0.09418410, -0.92938870), vec2(0.34495938, 0.29387760),
    vec2(-0.91588581, 0.45771432), vec2(-0.81544232, -0.87912464),
    vec2(-0.38277543, 0.27676845), vec2(0.53742981, -0.47373420),
    vec2(0.79197514, 0.19090188), vec2(0.19984126, 0.78641367));

// Gamma 2 instead of 2.2: indistinguishable here, and pow() is slow on software GL.
vec3 to_linear(vec3 c) { return c * c; }
vec3 to_srgb(vec3 c) { return sqrt(clamp(c, 0.0, 1.0)); }

// 1 = fully lit by the key light, 0 = fully in shadow (percentage-closer filtering).
float key_visibility(vec3 pos, vec3 normal, float radius_texels) {
    if (u_shadows == 0) return 1.0;
    vec4 lp = u_light_vp * vec4(pos + normal * u_shadow_bias, 1.0);
    vec3 c = lp.xyz / lp.w * 0.5 + 0.5;
    if (c.x <= 0.0 || c.x >= 1.0 || c.y <= 0.0 || c.y >= 1.0) return 1.0;
    c.z = min(c.z, 1.0);
    float lit = 0.0;
    for (int i = 0; i < 4; i++) {
        lit += texture(u_shadow_map, vec3(c.xy + POISSON[i] * radius_texels * u_shadow_texel, c.z));
    }
    if (lit < 0.001 || lit > 3.999) return lit / 4.0;
    for (int i = 4; i < 12; i++) {
        lit += texture(u_shadow_map, vec3(c.xy + POISSON[i] * radius_texels * u_shadow_texel, c.z));
    }
    return lit / 12.0;
}
"""

MESH_VS = """
#version 330
uniform mat4 u_vp;
in vec3 in_pos;
in vec3 in_normal;
in vec3 in_color;
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_color;
void main() {
    v_pos = in_pos;
    v_normal = in_normal;
    v_color = in_color;
    gl_Position = u_vp * vec4(in_pos, 1.0);
}
"""

MESH_FS = (
    """
#version 330
"""
    + _COMMON
    + """
uniform vec3 u_eye;
uniform vec3 u_light_dir;       // unit, towards the key light
uniform vec3 u_key;             // key light colour * intensity (linear)
uniform vec3 u_sky;             // hemisphere ambient from above (linear)
uniform vec3 u_ground;          // hemisphere ambient from below (linear)
uniform float u_fill;           // camera-side fill light intensity
uniform float u_specular;       // specular strength
uniform float u_shininess;      // Blinn-Phong exponent
uniform vec3 u_backface_tint;   // albedo multiplier for back faces (the inside of cloth)
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_color;
out vec4 f_color;

void main() {
    vec3 n = normalize(v_normal);
    vec3 albedo = to_linear(v_color);
    if (!gl_FrontFacing) {      // two-sided: light the inside with the flipped normal
        n = -n;
        albedo *= u_backface_tint;
    }
    vec3 view = normalize(u_eye - v_pos);
    vec3 L = u_light_dir;
    float ndl = max(dot(n, L), 0.0);
    float vis = ndl > 0.0 ? key_visibility(v_pos, n, 1.5) : 0.0;
    vec3 h = normalize(L + view);
    float spec = ndl > 0.0 ? pow(max(dot(n, h), 0.0), u_shininess) : 0.0;
    vec3 ambient = mix(u_ground, u_sky, 0.5 + 0.5 * n.z);
    vec3 color = albedo * (ambient + u_key * ndl * vis + u_fill * max(dot(n, view), 0.0))
               + u_key * u_specular * spec * vis;
    f_color = vec4(to_srgb(color), 1.0);
}
"""
)

FLOOR_VS = """
#version 330
uniform mat4 u_vp;
uniform vec2 u_floor_center;
uniform float u_floor_half;
in vec2 in_corner;
out vec3 v_pos;
void main() {
    v_pos = vec3(u_floor_center + in_corner * u_floor_half, 0.0);
    gl_Position = u_vp * vec4(v_pos, 1.0);
}
"""

FLOOR_FS = (
    """
#version 330
"""
    + _COMMON
    + """
uniform vec2 u_floor_center;
uniform float u_floor_radius;   // the floor fades into the background towards this radius
uniform float u_tile;           // checker square size, metres
uniform vec3 u_tile_a;          // sRGB
uniform vec3 u_tile_b;          // sRGB
uniform vec3 u_background;      // sRGB
uniform float u_shadow_strength;
in vec3 v_pos;
out vec4 f_color;

// Box-filtered checkerboard (no moire in the distance), 0 or 1 away from edges.
float checker(vec2 p) {
    vec2 w = fwidth(p) + 1e-4;
    vec2 lo = abs(fract((p - 0.5 * w) * 0.5) - 0.5);
    vec2 hi = abs(fract((p + 0.5 * w) * 0.5) - 0.5);
    vec2 i = 2.0 * (lo - hi) / w;
    return 0.5 - 0.5 * i.x * i.y;
}

void main() {
    vec3 albedo = mix(to_linear(u_tile_a), to_linear(u_tile_b), checker(v_pos.xy / u_tile));
    float vis = key_visibility(v_pos, vec3(0.0, 0.0, 1.0), 2.5);
    vec3 color = to_srgb(albedo * (1.0 - u_shadow_strength * (1.0 - vis)));
    float fade = smoothstep(0.55, 1.0, length(v_pos.xy - u_floor_center) / u_floor_radius);
    f_color = vec4(mix(color, u_background, fade), 1.0);
}
"""
)
