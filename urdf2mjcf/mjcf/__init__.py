"""The MJCF document, which the passes from emit on take and return.

====================  ==========================================================
``document``          :class:`~urdf2mjcf.mjcf.document.Document` (tree, asset files,
                      home pose), the top-level sections and the one writer
``joints``            the document's joints and their ``qpos`` layout; keyframes
                      re-padded when joints are added
``compile``           compiling a document with MuJoCo (at home, without visuals,
                      the certificate's passive second), shared by the passes
====================  ==========================================================

A pass over the document never runs another pass: the pipeline (``urdf2mjcf.api``,
``urdf2mjcf.facility.build``) runs them in order.
"""
