// facecap review page: plays a facecap GLB (morph-target weights animation, marker nodes
// `marker:<label>` with translation animation) in three.js, with an optional error heat map.
// Written into the page by facecap.report.review_page; the config comes from the JSON script
// `facecap-config`, the GLB from the base64 script `facecap-glb` (embedded) or `config.glbUrl`.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';

const config = JSON.parse(document.getElementById('facecap-config').textContent);
const nFrames = config.nFrames;
const rate = config.rate;

const canvas = document.getElementById('canvas');
const view = document.getElementById('view');
const frameLabel = document.getElementById('frame');
const timeLabel = document.getElementById('time');
const scrubber = document.getElementById('scrubber');
const playButton = document.getElementById('play');
const markersToggle = document.getElementById('markers-toggle');
const errorToggle = document.getElementById('error-toggle');
const legend = document.getElementById('legend');
const message = document.getElementById('message');
const picked = document.getElementById('picked');

const api = {
	ready: false,
	nFrames,
	rate,
	loadError: null,
	renderCount: 0,
	setFrame,
	frame: () => current,
	play,
	pause,
	playing: () => playing,
	setMarkersVisible,
	setErrorVisible,
	setCamera,
	resetCamera,
	markerLabels: () => markers.map( ( m ) => m.label ),
	// World positions of the marker nodes and the face's morph weights as three.js shows them now.
	markerPositions: () => markers.map( ( m ) => m.node.getWorldPosition( new THREE.Vector3() ).toArray() ),
	morphWeights: () => ( faceMesh && faceMesh.morphTargetInfluences ? Array.from( faceMesh.morphTargetInfluences ) : [] ),
	canvasSize: () => [ canvas.clientWidth, canvas.clientHeight ],
};
window.facecapReview = api;

const renderer = new THREE.WebGLRenderer( { canvas, antialias: true, preserveDrawingBuffer: true } );
renderer.setPixelRatio( window.devicePixelRatio );
const scene = new THREE.Scene();
scene.background = new THREE.Color( config.background );
const perspective = new THREE.PerspectiveCamera( 30, 1, 0.01, 1000 );
let camera = perspective;
let orthographic = null;
scene.add( perspective );
// A head light (attached to the camera) so the face stays lit from any orbit angle, plus a
// sky/ground fill for the shadowed side.
scene.add( new THREE.HemisphereLight( 0xffffff, 0x404040, 1.6 ) );
const keyLight = new THREE.DirectionalLight( 0xffffff, 1.8 );
keyLight.position.set( - 0.3, 0.4, 1.0 );
perspective.add( keyLight );
perspective.add( keyLight.target );
keyLight.target.position.set( 0, 0, - 1 );

const controls = new OrbitControls( perspective, canvas );
controls.addEventListener( 'change', requestRender );

const mixer = new THREE.AnimationMixer( scene );
const actions = [];
const markers = [];
let faceMesh = null;
let neutralMaterial = null;
let heatMaterial = null;
let errorData = null;
let errorRow = - 1;
let current = 0;
let playing = false;
let playClockStart = 0;
let playTimeStart = 0;
let renderPending = false;
let frameBox = null;

function renderNow() {

	renderer.render( scene, camera );
	api.renderCount += 1;

}

function requestRender() {

	if ( renderPending ) return;
	renderPending = true;
	requestAnimationFrame( () => {

		renderPending = false;
		renderNow();

	} );

}

function resize() {

	const width = Math.max( 1, view.clientWidth );
	const height = Math.max( 1, view.clientHeight );
	renderer.setSize( width, height, false );
	perspective.aspect = width / height;
	perspective.updateProjectionMatrix();
	renderNow();

}

function fail( text ) {

	api.loadError = text;
	message.textContent = text;
	message.hidden = false;
	console.error( 'facecap review page: ' + text );

}

function decodeBase64( text ) {

	if ( typeof Uint8Array.fromBase64 === 'function' ) return Uint8Array.fromBase64( text.trim() );
	const binary = atob( text.trim() );
	const bytes = new Uint8Array( binary.length );
	for ( let i = 0; i < binary.length; i ++ ) bytes[ i ] = binary.charCodeAt( i );
	return bytes;

}

async function glbBytes() {

	const embedded = document.getElementById( 'facecap-glb' );
	if ( embedded ) return decodeBase64( embedded.textContent ).buffer;
	let response;
	try {

		response = await fetch( config.glbUrl );

	} catch ( error ) {

		throw new Error( `could not read ${config.glbUrl} (${error.message}); a page that links its GLB must be ` +
			'opened through a local web server (facecap view FOLDER), not as a file' );

	}

	if ( ! response.ok ) throw new Error( `could not read ${config.glbUrl}: HTTP ${response.status}` );
	return await response.arrayBuffer();

}

// Time t (s) into the take: every action sampled at t exactly (action.time set, then a zero
// step: with a zero step three.js evaluates the clip at action.time without looping).
function showTime( t ) {

	for ( const action of actions ) action.time = Math.min( Math.max( t, 0 ), action.getClip().duration );
	mixer.update( 0 );
	const frame = Math.min( nFrames - 1, Math.max( 0, Math.floor( t * rate + 1e-6 ) ) );
	current = frame;
	frameLabel.textContent = String( frame );
	scrubber.value = String( frame );
	timeLabel.textContent = ( frame / rate ).toFixed( 3 ) + ' s';
	updateErrorColours();

}

function setFrame( index ) {

	const frame = Math.min( nFrames - 1, Math.max( 0, Math.round( Number( index ) ) ) );
	showTime( frame / rate );
	if ( playing ) {

		playClockStart = performance.now();
		playTimeStart = frame / rate;

	}

	renderNow();
	return frame;

}

function tick( now ) {

	if ( ! playing ) return;
	const span = nFrames / rate;
	const t = ( playTimeStart + ( now - playClockStart ) / 1000 ) % span;
	showTime( t );
	renderNow();
	requestAnimationFrame( tick );

}

function play() {

	if ( playing || ! api.ready ) return;
	playing = true;
	playButton.textContent = 'Pause';
	playClockStart = performance.now();
	playTimeStart = current / rate;
	requestAnimationFrame( tick );

}

function pause() {

	playing = false;
	playButton.textContent = 'Play';

}

function setMarkersVisible( visible ) {

	for ( const m of markers ) m.sphere.visible = Boolean( visible );
	markersToggle.checked = Boolean( visible );
	renderNow();

}

function setErrorVisible( visible ) {

	if ( ! faceMesh ) return;
	const on = Boolean( visible ) && errorData !== null;
	faceMesh.material = on ? heatMaterial : neutralMaterial;
	errorToggle.checked = on;
	legend.hidden = ! on;
	if ( on ) updateErrorColours();
	renderNow();

}

function updateErrorColours() {

	if ( errorData === null ) return;
	const frames = errorData.frames;
	let row = 0;
	while ( row + 1 < frames.length && frames[ row + 1 ] <= current ) row ++;
	if ( row === errorRow ) return;
	errorRow = row;
	const n = errorData.n;
	const levels = errorData.levels.subarray( row * n, ( row + 1 ) * n );
	const lut = errorData.lut;
	const colour = faceMesh.geometry.getAttribute( 'color' );
	const out = colour.array;
	for ( let i = 0; i < n; i ++ ) {

		const q = levels[ i ] * 3;
		out[ 3 * i ] = lut[ q ];
		out[ 3 * i + 1 ] = lut[ q + 1 ];
		out[ 3 * i + 2 ] = lut[ q + 2 ];

	}

	colour.needsUpdate = true;
	document.getElementById( 'legend-frame' ).textContent =
		frames.length > 1 ? `error at frame ${frames[ row ]}` : 'error over the take';

}

// Orthographic front view (camera on +z looking toward -z, y up) of the world window
// [left, right] x [bottom, top]: the same projection as facecap.report.render_mesh's 'front'.
function setCamera( spec ) {

	if ( ! frameBox ) throw new Error( 'setCamera: the GLB has not loaded yet' );
	const depth = frameBox.max.z - frameBox.min.z + frameBox.getSize( new THREE.Vector3() ).length();
	orthographic = new THREE.OrthographicCamera( spec.left, spec.right, spec.top, spec.bottom, 0, 4 * depth );
	orthographic.position.set( 0, 0, frameBox.max.z + depth );
	orthographic.add( keyLight );
	orthographic.add( keyLight.target );
	scene.add( orthographic );
	camera = orthographic;
	controls.enabled = false;
	renderNow();
	return { left: spec.left, right: spec.right, bottom: spec.bottom, top: spec.top };

}

function resetCamera() {

	if ( orthographic ) {

		perspective.add( keyLight );
		perspective.add( keyLight.target );
		scene.remove( orthographic );
		orthographic = null;

	}

	camera = perspective;
	controls.enabled = true;
	frameFace();

}

// Default view: in front of the face (+z, y up, as glTF and facecap's meshes face), far enough
// to show the whole bounding box of the rest shape with a margin.
function frameFace() {

	const centre = frameBox.getCenter( new THREE.Vector3() );
	const size = frameBox.getSize( new THREE.Vector3() );
	const halfFov = THREE.MathUtils.degToRad( perspective.fov / 2 );
	const fitHeight = 0.5 * Math.max( size.y, size.x / perspective.aspect ) / Math.tan( halfFov );
	const distance = 1.15 * fitHeight + 0.5 * size.z;
	const diagonal = Math.max( size.length(), 1e-9 );
	perspective.near = diagonal / 200;
	perspective.far = diagonal * 50 + distance;
	perspective.position.set( centre.x, centre.y, centre.z + distance );
	perspective.updateProjectionMatrix();
	controls.target.copy( centre );
	controls.update();
	renderNow();

}

function buildErrorData() {

	const info = config.error;
	if ( ! info ) return null;
	const element = document.getElementById( 'facecap-error' );
	const levels = decodeBase64( element.textContent );
	const n = faceMesh.geometry.getAttribute( 'position' ).count;
	if ( info.n !== n || levels.length !== info.frames.length * n ) {

		fail( `the error data holds ${info.n} values per frame but the mesh has ${n} vertices` );
		return null;

	}

	// The colour table is in sRGB (matplotlib's); three.js works in linear colour.
	const lut = new Float32Array( info.lut.length * 3 );
	const c = new THREE.Color();
	info.lut.forEach( ( rgb, k ) => {

		c.setRGB( rgb[ 0 ], rgb[ 1 ], rgb[ 2 ], THREE.SRGBColorSpace );
		lut[ 3 * k ] = c.r;
		lut[ 3 * k + 1 ] = c.g;
		lut[ 3 * k + 2 ] = c.b;

	} );
	faceMesh.geometry.setAttribute( 'color', new THREE.Float32BufferAttribute( new Float32Array( 3 * n ), 3 ) );
	drawLegend( info );
	return { n, frames: info.frames, levels, lut };

}

function drawLegend( info ) {

	const bar = document.getElementById( 'legend-bar' );
	const context = bar.getContext( '2d' );
	const colours = info.lut.length - 1; // the last entry is the no-value grey
	for ( let x = 0; x < bar.width; x ++ ) {

		const rgb = info.lut[ Math.min( colours - 1, Math.floor( x / bar.width * colours ) ) ];
		context.fillStyle = `rgb(${255 * rgb[ 0 ]}, ${255 * rgb[ 1 ]}, ${255 * rgb[ 2 ]})`;
		context.fillRect( x, 0, 1, bar.height );

	}

	document.getElementById( 'legend-low' ).textContent = info.range[ 0 ].toPrecision( 3 );
	document.getElementById( 'legend-high' ).textContent = info.range[ 1 ].toPrecision( 3 ) + ' mm';

}

function findNodes( gltf ) {

	const json = gltf.parser.json;
	const nodeName = ( object ) => {

		const association = gltf.parser.associations.get( object );
		return association && association.nodes !== undefined ? ( json.nodes[ association.nodes ].name || '' ) : '';

	};
	const candidates = [];
	gltf.scene.traverse( ( object ) => {

		const name = nodeName( object );
		// Markers: nodes named `marker:<label>`, or the children of a node named `Markers`
		// (facecap.io.write_gltf, whose marker nodes carry a small mesh of their own).
		if ( name.startsWith( 'marker:' ) ) markers.push( { node: object, label: name.slice( 7 ), sphere: null } );
		else if ( object.parent && nodeName( object.parent ) === 'Markers' ) markers.push( { node: object, label: name, sphere: null } );
		else if ( object.isMesh && ! ( object.parent && markers.some( ( m ) => m.node === object.parent ) ) ) candidates.push( object );

	} );
	// The face: the mesh with morph targets, else the one with the most vertices.
	const count = ( m ) => m.geometry.getAttribute( 'position' ).count;
	candidates.sort( ( a, b ) => ( ( b.morphTargetInfluences ? 1 : 0 ) - ( a.morphTargetInfluences ? 1 : 0 ) ) ||
		( count( b ) - count( a ) ) );
	return candidates[ 0 ] || null;

}

function addMarkerSpheres() {

	const radius = 0.006 * frameBox.getSize( new THREE.Vector3() ).length();
	const geometry = new THREE.SphereGeometry( 1, 16, 12 );
	const material = new THREE.MeshStandardMaterial( { color: 0x21b8e8, roughness: 0.4, metalness: 0 } );
	const worldScale = new THREE.Vector3();
	for ( const m of markers ) {

		if ( m.node.isMesh ) { // the file's own marker mesh: show that one

			m.sphere = m.node;
			m.node.userData.markerLabel = m.label;
			continue;

		}

		m.sphere = new THREE.Mesh( geometry, material );
		// The parent's scale: the node's own may be animated to 0 to hide the marker in a gap.
		( m.node.parent || m.node ).getWorldScale( worldScale );
		m.sphere.scale.set( radius / worldScale.x, radius / worldScale.y, radius / worldScale.z );
		m.sphere.userData.markerLabel = m.label;
		m.node.add( m.sphere );

	}

}

function pickMarker( event ) {

	if ( markers.length === 0 || ! markersToggle.checked ) return;
	const rect = canvas.getBoundingClientRect();
	const pointer = new THREE.Vector2( ( event.clientX - rect.left ) / rect.width * 2 - 1,
		- ( ( event.clientY - rect.top ) / rect.height ) * 2 + 1 );
	const raycaster = new THREE.Raycaster();
	raycaster.setFromCamera( pointer, camera );
	const hits = raycaster.intersectObjects( markers.map( ( m ) => m.sphere ), false );
	picked.textContent = hits.length ? `marker ${hits[ 0 ].object.userData.markerLabel}` : '';

}

async function load() {

	const bytes = await glbBytes();
	const gltf = await new GLTFLoader().setMeshoptDecoder( MeshoptDecoder ).parseAsync( bytes, '' );
	scene.add( gltf.scene );
	faceMesh = findNodes( gltf );
	if ( ! faceMesh ) throw new Error( 'the GLB holds no mesh' );
	const geometry = faceMesh.geometry;
	// Without normals in the file, shade per face (derivatives of the morphed positions): smooth
	// normals computed here would not follow the morph targets.
	const flat = geometry.getAttribute( 'normal' ) === undefined;
	neutralMaterial = new THREE.MeshStandardMaterial( {
		color: 0xc8c0ba, roughness: 0.65, metalness: 0, side: THREE.DoubleSide, flatShading: flat,
	} );
	heatMaterial = new THREE.MeshBasicMaterial( { vertexColors: true, side: THREE.DoubleSide } );
	faceMesh.material = neutralMaterial;

	gltf.scene.updateMatrixWorld( true );
	frameBox = new THREE.Box3().setFromObject( faceMesh );
	addMarkerSpheres();
	for ( const clip of gltf.animations ) {

		const action = mixer.clipAction( clip );
		action.setLoop( THREE.LoopOnce, 1 );
		action.clampWhenFinished = true;
		action.play();
		actions.push( action );

	}

	errorData = buildErrorData();
	errorToggle.disabled = errorData === null;
	markersToggle.disabled = markers.length === 0;
	document.getElementById( 'marker-count' ).textContent = String( markers.length );
	scrubber.max = String( nFrames - 1 );
	resize();
	frameFace();
	setFrame( 0 );
	api.ready = true;

}

playButton.addEventListener( 'click', () => ( playing ? pause() : play() ) );
scrubber.addEventListener( 'input', () => setFrame( Number( scrubber.value ) ) );
markersToggle.addEventListener( 'change', () => setMarkersVisible( markersToggle.checked ) );
errorToggle.addEventListener( 'change', () => setErrorVisible( errorToggle.checked ) );
canvas.addEventListener( 'click', pickMarker );
window.addEventListener( 'keydown', ( event ) => {

	if ( event.target instanceof HTMLInputElement && event.target.type !== 'checkbox' ) return;
	if ( event.key === ' ' ) {

		event.preventDefault();
		playing ? pause() : play();

	} else if ( event.key === 'ArrowRight' ) setFrame( current + 1 );
	else if ( event.key === 'ArrowLeft' ) setFrame( current - 1 );

} );
new ResizeObserver( () => {

	if ( frameBox ) resize();

} ).observe( view );

load().catch( ( error ) => fail( error.message || String( error ) ) );
