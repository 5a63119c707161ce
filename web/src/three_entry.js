// The parts of three.js the report's 3D viewer uses, exposed as window.THREE (see build.mjs).
// Named imports let esbuild drop the rest of the library.
import {
  AmbientLight, AxesHelper, Box3, BufferAttribute, BufferGeometry, Color, DirectionalLight,
  DoubleSide, Float32BufferAttribute, GridHelper, Mesh, MeshPhongMaterial, PerspectiveCamera,
  Points, PointsMaterial, Scene, Sphere, Vector3, WebGLRenderer, LineSegments, EdgesGeometry,
  LineBasicMaterial, Group, Sprite, SpriteMaterial, CanvasTexture,
} from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

window.THREE = {
  AmbientLight, AxesHelper, Box3, BufferAttribute, BufferGeometry, Color, DirectionalLight,
  DoubleSide, Float32BufferAttribute, GridHelper, Mesh, MeshPhongMaterial, PerspectiveCamera,
  Points, PointsMaterial, Scene, Sphere, Vector3, WebGLRenderer, LineSegments, EdgesGeometry,
  LineBasicMaterial, Group, Sprite, SpriteMaterial, CanvasTexture, OrbitControls,
};
