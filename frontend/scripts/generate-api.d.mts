// Types of generate-api.mjs, for the staleness test (src/lib/api/generatedApi.test.ts).
export declare const OPENAPI_PATH: string;
export declare const API_TS_PATH: string;
export declare function generateApiTs(documentText: string): Promise<string>;
