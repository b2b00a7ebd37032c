#version 450
// View samples, pass 1 (raster): the id + 1 of the nearest triangle per
// pixel centre (0 where nothing is seen, the clear value).

layout(location = 0) flat in uint triangle_id;
layout(location = 0) out uint id_plus_one;

void main() {
    id_plus_one = triangle_id + 1u;
}
