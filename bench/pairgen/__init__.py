"""An independent generator of grounding pairs: its own meshes, materials, Open3D ray caster and corruptions
(nothing shared with the project's MuJoCo scenes or renderer), so bench/grounding.py can show what the method
does on images the project did not render itself."""
