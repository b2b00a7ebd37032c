// Division rounded as IEEE says (to nearest, ties to even) for finite a and
// b != 0 whose quotient is a normal number or overflows: Vulkan lets `/` be
// 2.5 ulp off (NVIDIA's is; lavapipe's is exact), and the results that
// use this must equal their CPU twin's bits. a / b = (ma / mb) 2^(ea - eb)
// with 24-bit integer mantissas, whose quotient is formed bit by bit with
// its remainder.
#ifndef EXACT_DIV_GLSL
#define EXACT_DIV_GLSL

float div_rn(float a, float b) {
    if (a == 0.0) {
        return a;
    }
    int ea, eb;
    float fa = frexp(abs(a), ea), fb = frexp(abs(b), eb); // in [0.5, 1)
    uint ma = uint(fa * 16777216.0), mb = uint(fb * 16777216.0); // in [2^23, 2^24)
    int e = ea - eb;
    uint r = ma;
    if (r < mb) {
        r <<= 1;
        e -= 1;
    }
    // a / b = (r / mb) 2^e with r / mb in [1, 2): 24 quotient bits.
    uint q = 0u;
    for (int i = 0; i < 24; i++) {
        q <<= 1;
        if (r >= mb) {
            q |= 1u;
            r -= mb;
        }
        r <<= 1;
    }
    // r is twice the remainder: above mb rounds up. It never equals mb: a
    // quotient of two floats is never halfway between two floats.
    if (r > mb) {
        q += 1u;
    }
    float s = (a < 0.0) != (b < 0.0) ? -1.0 : 1.0;
    return s * ldexp(float(q), e - 23);
}

#endif
