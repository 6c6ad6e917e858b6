// Depth convention (render/depth.py): reversed-Z, infinite far plane, window depth = near / d
// (1 at the near plane, 0 at infinity). DEPTH_ZERO_TO_ONE is 1 when glClipControl(ZERO_TO_ONE)
// is in effect (NDC z = window depth) and 0 on the conventional clip range (NDC z = 2 depth - 1);
// the program cache defines it per context.
#ifndef DEPTH_ZERO_TO_ONE
#define DEPTH_ZERO_TO_ONE 1
#endif

#if DEPTH_ZERO_TO_ONE
const float NDC_Z_AT_INFINITY = 0.0;
#else
const float NDC_Z_AT_INFINITY = -1.0;
#endif
