//! examples/api.rs, the library API's runnable example, renders what it says: the
//! triangle's vertex colours at its corners, the sphere behind it, background elsewhere.

#[path = "../../examples/api.rs"]
#[allow(dead_code)] // its `main` is the example's, not called here
mod api;

#[test]
fn the_api_example_renders_its_triangle_and_sphere() {
    let frame = api::render().unwrap();
    assert_eq!((frame.width, frame.height), (160, 120));
    // Device pixels of the corners (-2,-1.5,-5) and (2,-1.5,-5), (0,1.8,-5): a 50° fov, so
    // 1 unit at depth 5 is 60 / (5 tan 25°) = 25.7 px.
    let cs = |x, y| frame.param_at("Cs", x, y).unwrap();
    let near_red = cs(34, 95);
    assert!(
        near_red[0] > 0.85 && near_red[1] < 0.15 && near_red[2] < 0.15,
        "{near_red:?}"
    );
    let near_green = cs(125, 95);
    assert!(near_green[1] > 0.85 && near_green[0] < 0.15, "{near_green:?}");
    let near_blue = cs(80, 18);
    assert!(near_blue[2] > 0.85 && near_blue[0] < 0.15, "{near_blue:?}");
    // The sphere (centre (1.5, 0.5, -9), radius 2) right of the triangle's top: grey.
    assert_eq!(cs(110, 40), vec![0.7, 0.7, 0.7]);
    // A corner of the image: nothing drawn.
    assert!(!frame.written(2, 2));
}
