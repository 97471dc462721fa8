// Types of generate-api.mjs, for the staleness tests (src/lib/api/generatedApi.test.ts,
// src/lib/plant/plantApi.test.ts).
export declare const OPENAPI_PATH: string;
export declare const API_TS_PATH: string;
export declare const PLANT_OPENAPI_PATH: string;
export declare const PLANT_API_TS_PATH: string;
export declare function generateApiTs(documentText: string, documentName?: string): Promise<string>;
