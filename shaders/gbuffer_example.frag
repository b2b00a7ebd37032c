#version 450
// examples/gbuffer.rs: the visibility buffer, triangle index + 1 per pixel
// (0 where nothing is drawn). Not used by the library.

layout(location = 0) flat in uint triangle;
layout(location = 0) out uint id_plus_one;

void main() {
    id_plus_one = triangle + 1u;
}
