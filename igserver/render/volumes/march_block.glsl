// One volume's march constants (render/volumes/march_block.py packs them; every member a vec4, so
// the std140 rows are 16 bytes in this order). Camera-relative metres.
#define MAX_SLABS 8
layout(std140, binding = BLOCK_VOLUME) uniform VolumeBlock {
    vec4 u_slab_min[MAX_SLABS];  // xyz: AABB of slab i of the (bent) container (Volume.slabs), drawn
    vec4 u_slab_max[MAX_SLABS];  //      farthest first as instance i
    vec4 u_base_step;            // xyz base centre; w longest march step (box diagonal / steps)
    vec4 u_extent_voxel;         // xyz radius, radius, height; w the texture's voxel size
    vec4 u_lean_sigma_g;         // xy horizontal offset of the axis at the top (wind); z extinction
                                 // at density 1 (1/m); w Henyey-Greenstein asymmetry (smoke)
    vec4 u_glow_pos_albedo;      // xyz the fire's light (smoke); w x the profile's albedo (sooty smoke)
    vec4 u_glow_intensity_;      // xyz cd per channel of that light (0 when none); w the keyframe
                                 // blend: weight of the next model (BLEND)
    vec4 u_emission_;            // xyz cd/m^2 of colour 1 (fire); w per-frame shift of the start
                                 // jitter, in [0,1)
};
#define u_base u_base_step.xyz
#define u_step u_base_step.w
#define u_extent u_extent_voxel.xyz
#define u_voxel u_extent_voxel.w
#define u_lean u_lean_sigma_g.xy
#define u_sigma u_lean_sigma_g.z
#define u_hg_g u_lean_sigma_g.w
#define u_glow_pos u_glow_pos_albedo.xyz
#define u_albedo_scale u_glow_pos_albedo.w
#define u_glow_intensity u_glow_intensity_.xyz
#define u_emission u_emission_.xyz
#define u_blend u_glow_intensity_.w
#define u_jitter_offset u_emission_.w
